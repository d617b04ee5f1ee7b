//! `icefem` command line: parses arguments, runs the library, reports.

use anyhow::{Context, Result};
use clap::{Parser, Subcommand};
use icefem::bench::{self, BenchCommand, SolverOptions};
use icefem::eta::{format_duration, Eta};
use icefem::export::{ExportFormat, ExportOptions};
use icefem::output::FrameReader;
use icefem::render::{
    self, Background, ColorField, Cut, Lens, RenderOptions, Shading, Style, View,
};
use icefem::run::{run_on, Processes, Progress, RunOptions};
use icefem::scene::Scene;
use icefem::solver::{FillOrdering, LinearSolverKind};
use indicatif::{ProgressBar, ProgressStyle};
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Instant;

#[derive(Parser)]
#[command(
    name = "icefem",
    version,
    about = "Implicit FEM simulator of ice cracking as it freezes"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
    /// Print only errors (no progress, no summaries).
    #[arg(short, long, global = true, conflicts_with = "verbose")]
    quiet: bool,
    /// Print a line for every step of a run (also on a terminal).
    #[arg(short, long, global = true)]
    verbose: bool,
}

/// How much the commands print besides their results and errors.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Verbosity {
    Quiet,
    Normal,
    Verbose,
}

#[derive(Subcommand)]
enum Command {
    /// Simulate a scene and write every output frame to HDF5 (plus an XDMF sidecar). Built
    /// with the `mpi` feature, `mpirun -n N icefem run …` shares the run among N processes.
    Run {
        /// Scene file (TOML).
        scene: PathBuf,
        /// Output HDF5 file (default: the scene's [output] file, or <scene name>.h5).
        #[arg(long, short)]
        output: Option<PathBuf>,
        /// End time in seconds (overrides the scene).
        #[arg(long)]
        end_time: Option<f64>,
        /// Time step in seconds (overrides the scene).
        #[arg(long)]
        dt: Option<f64>,
        /// Continue FILE from its last complete frame (same scene).
        #[arg(long, value_name = "FILE", conflicts_with = "output")]
        resume: Option<PathBuf>,
        /// Replace the output file if it exists (only an icefem file that no run is writing;
        /// the old file stays until the new run has written a frame after its first step).
        #[arg(long, conflicts_with = "resume")]
        force: bool,
    },
    /// Time the solver on ice cubes of several sizes and print a markdown table (medians).
    Bench {
        /// Approximate tet counts, comma-separated.
        #[arg(long, value_delimiter = ',', default_value = "1000,10000,100000")]
        tets: Vec<usize>,
        /// Backward-Euler steps per run (per-step figures are medians over them).
        #[arg(long, default_value_t = 5)]
        steps: usize,
        /// Runs per size, each in a fresh process (so peak memory is per size).
        #[arg(long, default_value_t = 3)]
        repeats: usize,
        /// Linear solver.
        #[arg(long, value_enum, default_value = "cholesky")]
        solver: SolverArg,
        /// Cholesky fill-reducing ordering.
        #[arg(long, value_enum, default_value = "auto")]
        ordering: OrderingArg,
        /// Multigrid: set the hierarchy up at every Hessian refresh instead of reusing it.
        #[arg(long)]
        no_amg_reuse: bool,
        /// Internal: run one size in this process and print one result line.
        #[arg(long, hide = true)]
        single: Option<usize>,
        /// Instead: the per-step cost of contact (broad and narrow phase) against the elastic
        /// assembly, for two cubes stacked in a container (planes, then a triangle mesh).
        #[arg(long)]
        contact: bool,
        /// Instead: the cost of the fracture check per step and of one split (remesh and
        /// re-solve), on a pulled ice cube.
        #[arg(long)]
        fracture: bool,
        /// Print the tables as one JSON object (`tables`: columns and rows; `notes`).
        #[arg(long, conflicts_with = "single")]
        json: bool,
    },
    /// Render frames of a run to PNG (one frame or a numbered sequence) or an animated GIF.
    Render {
        /// HDF5 file written by `icefem run` (also one that was cut off).
        file: PathBuf,
        /// One frame (index of /frames/NNNNNN); default: the last complete frame.
        #[arg(long, conflicts_with = "frames")]
        frame: Option<usize>,
        /// Frames FIRST:LAST[:STEP] (LAST inclusive; empty parts mean first, last, 1).
        #[arg(long)]
        frames: Option<String>,
        /// Output: a .png (numbered _NNNNNN for several frames) or a .gif (animated).
        /// Default: RUN_NNNNNN.png for one frame, RUN.gif for several.
        #[arg(long, short)]
        output: Option<PathBuf>,
        #[command(flatten)]
        look: LookArgs,
        /// GIF frames per second.
        #[arg(long, default_value_t = 30.0)]
        fps: f64,
    },
    /// Compose the paper's figure: four frames side by side with their element and crack counts.
    Figure {
        /// HDF5 file written by `icefem run`.
        file: PathBuf,
        /// Frame indices of the panels, comma-separated; default: the frames written at the
        /// paper's steps 1200, 1600, 2000 and 2400, or four frames spread over a shorter run.
        #[arg(long, value_delimiter = ',')]
        frames: Vec<usize>,
        /// Output PNG (default RUN_figure.png).
        #[arg(long, short)]
        output: Option<PathBuf>,
        #[command(flatten)]
        look: LookArgs,
    },
    /// Export frames as surfaces with point attributes: a USD stage, or OBJ, PLY or VTU files.
    Export {
        /// HDF5 file written by `icefem run` (also one that was cut off).
        file: PathBuf,
        /// usd: one RUN.usda stage; obj: RUN_NNNNNN.obj per frame (geometry only); ply:
        /// RUN_ice_NNNNNN.ply and RUN_cracks_NNNNNN.ply per frame; vtu: the same as .vtu plus
        /// RUN.pvd for ParaView.
        #[arg(long, value_enum)]
        format: FormatArg,
        /// Frames FIRST:LAST[:STEP] (LAST inclusive; empty parts mean first, last, 1); default:
        /// every complete frame. Exported frames are numbered 0, 1, 2, ….
        #[arg(long)]
        frames: Option<String>,
        /// The .usda file (usd) or the folder (obj, ply, vtu). Default: RUN.usda, or the folder
        /// RUN_export/, beside FILE.
        #[arg(long, short)]
        output: Option<PathBuf>,
        /// Replace an earlier export's files (and remove its numbered files this one does not
        /// write); other files are never touched.
        #[arg(long)]
        force: bool,
        /// USD: the animation's frames per second (the stage's framesPerSecond).
        #[arg(long, default_value_t = icefem::export::DEFAULT_FPS)]
        fps: f64,
        /// USD: simulated seconds per second of animation (1: real time; 600 plays six hours
        /// in 36 s). A frame at time t sits at time code (t − t0) × fps / speed.
        #[arg(long, default_value_t = 1.0, allow_hyphen_values = true)]
        speed: f64,
    },
    /// Print what an icefem HDF5 file holds.
    Info {
        /// HDF5 file written by `icefem run`.
        file: PathBuf,
        /// Print it as one JSON object.
        #[arg(long)]
        json: bool,
    },
    /// Fill a closed triangle surface (OBJ, STL, PLY or a Gmsh surface) with tetrahedra,
    /// through Gmsh: a mesh for a scene's [mesh] or [[body]] file.
    Mesh {
        /// The closed surface (.obj, .stl, .ply or .msh); turned to face outward if needed.
        surface: PathBuf,
        /// Largest element size, in the surface file's units (the mesh keeps them: set the
        /// scene's `scale` for a file in millimetres).
        #[arg(long)]
        size: f64,
        /// Output Gmsh file (default: SURFACE with the extension .msh).
        #[arg(long, short)]
        output: Option<PathBuf>,
        /// Keep the surface's triangles as the mesh's boundary (default: remesh the surface at
        /// SIZE, so that the size holds everywhere).
        #[arg(long)]
        keep_surface: bool,
        /// The Gmsh program (default: $GMSH, gmsh on PATH, or target/gmsh-venv/bin/gmsh from
        /// `make gmsh`); the `gmsh` script of a Python environment is run with its Python.
        #[arg(long)]
        gmsh: Option<PathBuf>,
        /// Replace an existing output file.
        #[arg(long)]
        force: bool,
    },
}

fn main() {
    let cli = Cli::parse();
    let verbosity = match (cli.quiet, cli.verbose) {
        (true, _) => Verbosity::Quiet,
        (_, true) => Verbosity::Verbose,
        _ => Verbosity::Normal,
    };
    let result = match cli.command {
        Command::Run {
            scene,
            output,
            end_time,
            dt,
            resume,
            force,
        } => {
            let options = RunOptions {
                output: resume.clone().or(output),
                end_time,
                dt,
                resume: resume.is_some(),
                force,
            };
            run_scene(&scene, &options, verbosity)
        }
        Command::Bench {
            tets,
            steps,
            repeats,
            solver,
            ordering,
            no_amg_reuse,
            single,
            contact,
            fracture,
            json,
        } => {
            let options = SolverOptions {
                steps,
                linear: solver.into(),
                ordering: ordering.into(),
                amg_reuse: !no_amg_reuse,
            };
            let command = if contact {
                BenchCommand::Contact {
                    tets,
                    steps,
                    repeats,
                }
            } else if fracture {
                BenchCommand::Fracture { tets, repeats }
            } else if let Some(tets) = single {
                BenchCommand::Single { tets, options }
            } else {
                BenchCommand::Solver {
                    tets,
                    repeats,
                    options,
                }
            };
            if json {
                let mut lines = Vec::new();
                bench::run(&command, |line| lines.push(line.to_string()))
                    .map(|()| println!("{}", bench::json::tables_to_json(&lines)))
                    .map_err(Into::into)
            } else {
                bench::run(&command, |line| println!("{line}")).map_err(Into::into)
            }
        }
        Command::Render {
            file,
            frame,
            frames,
            output,
            look,
            fps,
        } => render_command(
            &file,
            frame,
            frames.as_deref(),
            output,
            &look,
            fps,
            verbosity,
        ),
        Command::Figure {
            file,
            frames,
            output,
            look,
        } => figure_command(&file, frames, output, &look, verbosity),
        Command::Export {
            file,
            format,
            frames,
            output,
            force,
            fps,
            speed,
        } => export_command(
            &file,
            &ExportOptions {
                format: format.into(),
                frames,
                output,
                force,
                fps,
                speed,
            },
            verbosity,
        ),
        Command::Mesh {
            surface,
            size,
            output,
            keep_surface,
            gmsh,
            force,
        } => mesh_command(
            &surface,
            output,
            &icefem::mesh::tetrahedralise::TetrahedraliseOptions {
                size,
                keep_surface,
                gmsh,
                force,
            },
            verbosity,
        ),
        Command::Info { file, json: false } => icefem::output::describe(&file)
            .map(|text| print!("{text}"))
            .map_err(Into::into),
        Command::Info { file, json: true } => icefem::output::summary(&file)
            .map_err(anyhow::Error::from)
            .and_then(|s| serde_json::to_string_pretty(&s).map_err(Into::into))
            .map(|text| println!("{text}")),
    };
    if let Err(e) = result {
        eprintln!("error: {}", message(&e));
        std::process::exit(1);
    }
}

/// `icefem mesh`: the surface's tet mesh, and what it is.
fn mesh_command(
    surface: &Path,
    output: Option<PathBuf>,
    options: &icefem::mesh::tetrahedralise::TetrahedraliseOptions,
    verbosity: Verbosity,
) -> Result<()> {
    let output = output.unwrap_or_else(|| surface.with_extension("msh"));
    let start = Instant::now();
    let made = icefem::mesh::tetrahedralise::tetrahedralise(surface, &output, options)?;
    if verbosity != Verbosity::Quiet {
        if made.reversed > 0 {
            eprintln!(
                "note: {}: {} of {} triangles faced inward and were turned outward",
                surface.display(),
                made.reversed,
                made.surface_triangles
            );
        }
        eprintln!(
            "{}: {} tets, {} nodes in {:.2} s ({}); volume {:.4e}, the surface encloses {:.4e} ({:+.2} %); physical volume \"body\", surface \"boundary\"",
            output.display(),
            made.tets,
            made.nodes,
            start.elapsed().as_secs_f64(),
            made.gmsh,
            made.mesh_volume,
            made.surface_volume,
            100.0 * (made.mesh_volume / made.surface_volume - 1.0)
        );
    }
    Ok(())
}

/// An error and its causes on one line, each cause once: a cause whose text its error already
/// shows (many errors quote their cause) is not repeated.
fn message(e: &anyhow::Error) -> String {
    let mut text = String::new();
    for cause in e.chain() {
        let line = cause.to_string();
        if !text.contains(&line) {
            if !text.is_empty() {
                text.push_str(": ");
            }
            text.push_str(&line);
        }
    }
    text
}

/// A picture's size without `--size` (for `figure`: each panel's), pixels.
const DEFAULT_SIZE: (usize, usize) = (800, 600);

/// How pictures look (`render` and `figure`).
#[derive(clap::Args)]
struct LookArgs {
    /// Picture size WIDTHxHEIGHT in pixels (default 800x600; for `figure`: the whole figure,
    /// the panels sized to fill it; without it each panel is 800x600).
    #[arg(long, value_parser = parse_size)]
    size: Option<(usize, usize)>,
    /// Camera: iso, front, side, top, or AZIMUTH,ELEVATION in degrees (z up).
    #[arg(long, default_value = "iso")]
    view: View,
    /// Point the camera looks at, X,Y,Z in m (default: the centre of the ice and obstacles).
    #[arg(long, value_parser = parse_point, allow_hyphen_values = true)]
    target: Option<[f64; 3]>,
    /// Distance from the camera to the target in m (default: the ice and obstacles fill 90 %
    /// of the picture).
    #[arg(long, value_parser = parse_distance)]
    distance: Option<f64>,
    /// Vertical field of view in degrees, in (0, 170).
    #[arg(long, default_value_t = render::camera::FIELD_OF_VIEW_DEG, value_parser = parse_fov)]
    fov: f64,
    /// Ice surface: glass (translucent, cracks inside show) or solid.
    #[arg(long, default_value = "glass")]
    style: Style,
    /// smooth (normals and fields interpolated from the vertices) or flat (one colour per
    /// element face: the elements show).
    #[arg(long, default_value = "smooth")]
    shading: Shading,
    /// Background: sky, white, black, #RRGGBB, or transparent (PNG only).
    #[arg(long, default_value = "sky")]
    background: Background,
    /// Colour the surface by freeze, plastic, stress (von Mises), principal (largest
    /// principal stress) or temperature (runs with [thermal]), with a colour bar.
    #[arg(long)]
    color_by: Option<ColorField>,
    /// Colour-bar range MIN,MAX (default: the range over the frames drawn).
    #[arg(long, value_parser = parse_range, allow_hyphen_values = true)]
    range: Option<(f64, f64)>,
    /// Cut the ice open: AXIS=VALUE (m, e.g. y=0.05) leaves out the elements between the
    /// camera and that plane, showing the inside.
    #[arg(long)]
    cut: Option<Cut>,
}

impl LookArgs {
    fn options(&self) -> RenderOptions {
        let (width, height) = self.size.unwrap_or(DEFAULT_SIZE);
        RenderOptions {
            width,
            height,
            view: self.view,
            lens: Lens {
                target: self.target.map(Into::into),
                distance: self.distance,
                fov: self.fov,
            },
            style: self.style,
            shading: self.shading,
            background: self.background,
            color_by: self.color_by,
            range: self.range,
            cut: self.cut,
        }
    }
}

fn parse_size(s: &str) -> Result<(usize, usize), String> {
    let bad = || {
        format!(
            "size {s:?}: expected WIDTHxHEIGHT, each {} … {} pixels",
            render::MIN_SIZE,
            render::MAX_SIZE
        )
    };
    let (w, h) = s.split_once('x').ok_or_else(bad)?;
    let side = |t: &str| {
        t.trim()
            .parse::<usize>()
            .ok()
            .filter(|v| (render::MIN_SIZE..=render::MAX_SIZE).contains(v))
    };
    Ok((side(w).ok_or_else(bad)?, side(h).ok_or_else(bad)?))
}

fn parse_point(s: &str) -> Result<[f64; 3], String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|t| t.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| format!("point {s:?}: expected X,Y,Z in m"))?;
    match v.as_slice() {
        [x, y, z] if v.iter().all(|c| c.is_finite()) => Ok([*x, *y, *z]),
        _ => Err(format!(
            "point {s:?}: expected three finite numbers X,Y,Z in m"
        )),
    }
}

fn parse_distance(s: &str) -> Result<f64, String> {
    s.trim()
        .parse::<f64>()
        .ok()
        .filter(|d| d.is_finite() && *d > 0.0)
        .ok_or_else(|| format!("distance {s:?}: expected a number of m > 0"))
}

fn parse_fov(s: &str) -> Result<f64, String> {
    s.trim()
        .parse::<f64>()
        .ok()
        .filter(|f| *f > 0.0 && *f < 170.0)
        .ok_or_else(|| format!("field of view {s:?}: expected degrees in (0, 170)"))
}

fn parse_range(s: &str) -> Result<(f64, f64), String> {
    let bad = || format!("range {s:?}: expected MIN,MAX with MIN < MAX");
    let (a, b) = s.split_once(',').ok_or_else(bad)?;
    match (a.trim().parse::<f64>(), b.trim().parse::<f64>()) {
        (Ok(a), Ok(b)) if a.is_finite() && b.is_finite() && a < b => Ok((a, b)),
        _ => Err(bad()),
    }
}

/// `icefem render`.
fn render_command(
    file: &Path,
    frame: Option<usize>,
    frames: Option<&str>,
    output: Option<PathBuf>,
    look: &LookArgs,
    fps: f64,
    verbosity: Verbosity,
) -> Result<()> {
    if !(fps.is_finite() && fps > 0.0) {
        anyhow::bail!("--fps must be > 0, got {fps}");
    }
    let reader = FrameReader::open(file)?;
    let list = render::select_frames(file, &reader, frame, frames)?;
    let output = output.unwrap_or_else(|| render::default_output(file, &list));
    let options = look.options();
    let summary = render::render_frames(&reader, &list, options, &output, fps)?;
    if verbosity == Verbosity::Quiet {
        return Ok(());
    }
    let n = summary.frames.max(1) as f64;
    match summary.files.as_slice() {
        [one] => println!("wrote {}", one.display()),
        files => println!(
            "wrote {} … {} ({} files)",
            files[0].display(),
            files[files.len() - 1].display(),
            files.len()
        ),
    }
    println!(
        "{} frames ({}x{}): per frame {:.1} ms reading, {:.1} ms drawing, {:.1} ms encoding",
        summary.frames,
        options.width,
        options.height,
        1e3 * summary.t_read / n,
        1e3 * summary.t_draw / n,
        1e3 * summary.t_encode / n
    );
    Ok(())
}

/// `icefem figure`.
fn figure_command(
    file: &Path,
    frames: Vec<usize>,
    output: Option<PathBuf>,
    look: &LookArgs,
    verbosity: Verbosity,
) -> Result<()> {
    let output = output.unwrap_or_else(|| render::sibling(file, "_figure.png"));
    if render::Target::of(&output)? != render::Target::Png {
        anyhow::bail!(
            "{}: a figure is one picture: give a .png output",
            output.display()
        );
    }
    let reader = FrameReader::open(file)?;
    let start = Instant::now();
    let (picture, panels) = render::figure(
        &reader,
        &render::FigureOptions {
            frames,
            panel: look.options(),
            size: look.size,
        },
    )?;
    render::save_png(&picture, &output)?;
    if verbosity == Verbosity::Quiet {
        return Ok(());
    }
    println!(
        "wrote {} ({}x{}, {:.2} s)",
        output.display(),
        picture.width,
        picture.height,
        start.elapsed().as_secs_f64()
    );
    println!(
        "| frame | step | time (s) | elements | crack polygons | crack triangles (both sides) | cracks |"
    );
    println!("|---|---|---|---|---|---|---|");
    for p in panels {
        println!(
            "| {} | {} | {:.1} | {} | {} | {} | {} |",
            p.frame, p.step, p.time, p.elements, p.crack_polygons, p.crack_triangles, p.cracks
        );
    }
    Ok(())
}

/// `icefem export`.
fn export_command(file: &Path, options: &ExportOptions, verbosity: Verbosity) -> Result<()> {
    let start = Instant::now();
    let reader = FrameReader::open(file)?;
    let summary = icefem::export::export(&reader, options)?;
    if verbosity == Verbosity::Quiet {
        return Ok(());
    }
    let seconds = start.elapsed().as_secs_f64();
    let per_frame = |t: f64| 1e3 * t / summary.frames.max(1) as f64;
    println!(
        "exported {} frames to {}: {} file{} in {:.2} s; per frame {:.1} ms reading, {:.1} ms surfaces, {:.1} ms writing",
        summary.frames,
        summary.output.display(),
        summary.files.len(),
        if summary.files.len() == 1 { "" } else { "s" },
        seconds,
        per_frame(summary.t_read),
        per_frame(summary.t_build),
        per_frame(summary.t_write),
    );
    Ok(())
}

#[derive(Clone, Copy, clap::ValueEnum)]
enum FormatArg {
    Usd,
    Obj,
    Ply,
    Vtu,
}

impl From<FormatArg> for ExportFormat {
    fn from(f: FormatArg) -> Self {
        match f {
            FormatArg::Usd => ExportFormat::Usd,
            FormatArg::Obj => ExportFormat::Obj,
            FormatArg::Ply => ExportFormat::Ply,
            FormatArg::Vtu => ExportFormat::Vtu,
        }
    }
}

#[derive(Clone, Copy, clap::ValueEnum)]
enum SolverArg {
    Cholesky,
    Cg,
    Amg,
    Auto,
}

impl From<SolverArg> for LinearSolverKind {
    fn from(s: SolverArg) -> Self {
        match s {
            SolverArg::Cholesky => LinearSolverKind::Cholesky,
            SolverArg::Cg => LinearSolverKind::Cg,
            SolverArg::Amg => LinearSolverKind::Amg,
            SolverArg::Auto => LinearSolverKind::Auto,
        }
    }
}

#[derive(Clone, Copy, clap::ValueEnum)]
enum OrderingArg {
    Auto,
    Amd,
    Metis,
}

impl From<OrderingArg> for FillOrdering {
    fn from(o: OrderingArg) -> Self {
        match o {
            OrderingArg::Auto => FillOrdering::Auto,
            OrderingArg::Amd => FillOrdering::Amd,
            OrderingArg::Metis => FillOrdering::Metis,
        }
    }
}

/// `icefem run` (a build without the `mpi` feature runs on one process). Started as one of
/// several processes by `mpirun`, it refuses: the copies would each run the whole scene and
/// write the same file. Process 0 alone says so.
#[cfg(not(feature = "mpi"))]
fn run_scene(scene_path: &Path, options: &RunOptions, verbosity: Verbosity) -> Result<()> {
    if let Some(launched) = icefem::launch::launched_processes() {
        if launched.rank == 0 {
            eprintln!(
                "error: this icefem was built without MPI, and {} processes were started (mpirun): each would run the whole scene alone and write the same output. Build with the feature (`make mpi`, or `cargo build --release --features mpi`) and start target/release/icefem with mpirun, or run icefem without mpirun on one process",
                launched.size
            );
        }
        std::process::exit(1);
    }
    exit_if_interrupted(&run_command(scene_path, options, None, verbosity)?);
    Ok(())
}

/// `icefem run`, shared among the processes `mpirun` started (on one process, the serial
/// run). Only process 0 reports; an error on any process ends them all.
#[cfg(feature = "mpi")]
fn run_scene(scene_path: &Path, options: &RunOptions, verbosity: Verbosity) -> Result<()> {
    let processes = icefem::distributed::MpiProcesses::init()?;
    // ICEFEM_DISTRIBUTE_ONE=1 takes the distributed path (PETSc) on one process too: the
    // one-process column of the scaling measurements.
    let one_shared = std::env::var_os("ICEFEM_DISTRIBUTE_ONE").is_some_and(|v| v == "1");
    if processes.size() == 1 && !one_shared {
        let summary = run_command(scene_path, options, None, verbosity)?;
        drop(processes);
        exit_if_interrupted(&summary);
        return Ok(());
    }
    // ICEFEM_WHOLE_MESH=1 makes every process hold the whole mesh where parts would do: the
    // comparison row of the scaling measurements.
    if std::env::var_os("ICEFEM_WHOLE_MESH").is_some_and(|v| v == "1") {
        processes.hold_whole_mesh();
    }
    // One process per core by default: each process's threads share the node's cores.
    if std::env::var_os("RAYON_NUM_THREADS").is_none() {
        let on_node = std::env::var("OMPI_COMM_WORLD_LOCAL_SIZE")
            .ok()
            .and_then(|n| n.parse::<usize>().ok())
            .unwrap_or(processes.size());
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
        let threads = (cores / on_node.max(1)).max(1);
        // Fails only if a pool exists already: then that one is used.
        let _ = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build_global();
    }
    let rank = processes.rank();
    let verbosity = if rank == 0 {
        verbosity
    } else {
        Verbosity::Quiet
    };
    let summary = match run_command(scene_path, options, Some(&processes), verbosity) {
        Ok(summary) => summary,
        Err(e) => {
            // Every process reads the same scene and options: an error in them is everyone's,
            // and process 0 says it once (its abort ends the others while they wait). Any
            // other error is the process's own.
            let everyones = e.downcast_ref::<icefem::scene::SceneError>().is_some()
                || matches!(
                    e.downcast_ref::<icefem::run::RunError>(),
                    Some(icefem::run::RunError::Scene(_) | icefem::run::RunError::Setup { .. })
                );
            if everyones && rank != 0 {
                std::thread::sleep(std::time::Duration::from_secs(10));
            }
            eprintln!(
                "error (process {rank} of {}): {}",
                processes.size(),
                message(&e)
            );
            processes.abort(1);
        }
    };
    let by_process = processes.traffic_by_process();
    if verbosity != Verbosity::Quiet {
        let iterations = summary.newton_iterations.max(1) as f64;
        eprintln!(
            "per Newton iteration ({} iterations), values of 8 bytes exchanged by each process:",
            summary.newton_iterations
        );
        for (p, report) in by_process.iter().enumerate() {
            let [sums, entries, gathered, halo] = report.traffic.map(|x| x as f64 / iterations);
            let [nodes, elements] = report.held;
            eprintln!(
                "  process {p}: sums {sums:.0}, matrix entries {entries:.0}, gathered {gathered:.0}, CG halo {halo:.0}; peak memory {:.0} MB ({:.0} MB before the solvers' set-up); holds {nodes} nodes, {elements} elements",
                report.peak_memory as f64 / 1e6,
                report.set_up_memory as f64 / 1e6,
            );
        }
    }
    drop(processes);
    exit_if_interrupted(&summary);
    Ok(())
}

fn run_command(
    scene_path: &Path,
    options: &RunOptions,
    processes: Option<&dyn Processes>,
    verbosity: Verbosity,
) -> Result<icefem::run::RunSummary> {
    let scene = Scene::load_shared(scene_path, processes.and_then(|p| p.mesh_sharing()))?;
    let interrupt = Arc::new(AtomicBool::new(false));
    {
        let flag = interrupt.clone();
        // Ctrl-C, SIGTERM (what `kill`, `timeout` and schedulers send) and SIGHUP all stop the
        // run after its current step, with the last state written. A second one while the
        // first is being honoured kills the process the usual way.
        ctrlc::set_handler(move || {
            if flag.swap(true, Ordering::SeqCst) {
                std::process::exit(130);
            }
        })
        .context("installing the Ctrl-C handler")?;
    }
    // Past a file-size limit (ulimit -f) a write fails with EFBIG instead of killing the
    // process, so the output's own check can report it (and the committed frames stay).
    // SAFETY: setting a signal's disposition to "ignore" is async-signal-safe and has no
    // handler to race with.
    unsafe {
        libc::signal(libc::SIGXFSZ, libc::SIG_IGN);
    }
    let (nodes, tets) = scene.counts();
    let talk = verbosity != Verbosity::Quiet;
    if talk {
        eprintln!(
            "icefem {}: {} — {} nodes, {} tets, {:?} {:?}, dt = {:e} s",
            env!("CARGO_PKG_VERSION"),
            scene_path.display(),
            nodes,
            tets,
            scene.settings.analysis,
            scene.model.elasticity.model,
            options.dt.unwrap_or(scene.settings.dt),
        );
        for notice in &scene.notices {
            eprintln!("note: {notice}");
        }
        for warning in &scene.warnings {
            eprintln!("warning: {warning}");
        }
    }
    // A bar on a terminal; lines (every 2 s, or every step with -v) in a log.
    let bar_shown = talk && verbosity != Verbosity::Verbose && std::io::stderr().is_terminal();
    let bar = ProgressBar::hidden();
    if bar_shown {
        bar.set_draw_target(indicatif::ProgressDrawTarget::stderr());
        bar.set_style(
            ProgressStyle::with_template("{bar:40} {pos}/{len} steps  {msg}")
                .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
    }
    let start = Instant::now();
    let mut last_log = Instant::now();
    let mut eta = Eta::new();
    // The scene's warnings are said again after the run, which lets go of the scene.
    let warnings = scene.warnings.clone();
    let summary = run_on(scene, options, processes, &interrupt, |p: &Progress| {
        let left = eta.update(start.elapsed().as_secs_f64(), p.time, p.end_time);
        let left = left.map_or_else(|| "…".to_string(), format_duration);
        if bar_shown {
            bar.set_length(p.total_steps);
            bar.set_position(p.step);
            bar.set_message(format!(
                "t = {:.4} s  [{} elapsed, ~{left} left]",
                p.time,
                format_duration(start.elapsed().as_secs_f64())
            ));
        } else if talk
            && (verbosity == Verbosity::Verbose
                || p.step == p.total_steps
                || last_log.elapsed().as_secs_f64() >= 2.0
                || p.step <= 1)
        {
            last_log = Instant::now();
            eprintln!(
                "step {}/{}  t = {:.4} s  newton {}  residual {:.2e} N  energy {:.4e} J  {:.3} s/step  ~{left} left",
                p.step,
                p.total_steps,
                p.time,
                p.report.newton.iterations,
                p.report.newton.residual,
                p.report.energies.total(),
                p.report.t_step
            );
        }
    })?;
    bar.finish_and_clear();
    // An interrupted run says so even when quiet (from the process that writes).
    let says_interrupted = summary.interrupted && processes.is_none_or(|p| p.writes());
    if !(talk || says_interrupted) {
        return Ok(summary);
    }
    eprintln!(
        "{} {} steps in {:.2} s ({} Newton iterations, max residual {:.2e} N); t = {:.4} s; {} frames in {}",
        if summary.interrupted { "interrupted after" } else { "done:" },
        summary.steps,
        start.elapsed().as_secs_f64(),
        summary.newton_iterations,
        summary.max_residual,
        summary.final_time,
        summary.frames,
        summary.output.display()
    );
    for line in summary.outcome.lines() {
        eprintln!("  {line}");
    }
    let (outgrown, gatherings, seconds) = summary.surface_gatherings;
    if gatherings > 0 {
        eprintln!(
            "  the processes gathered their ghost surfaces for ice–ice contact again {outgrown} \
             times as the ice moved ({gatherings} times in all, with the restart points: {seconds:.2} s)"
        );
    }
    for warning in warnings.iter().chain(&summary.outcome.warnings) {
        eprintln!("warning: {warning}");
    }
    if summary.interrupted {
        let launcher = processes.map_or(String::new(), |p| format!("mpirun -n {} ", p.count()));
        let mut again = format!(
            "{launcher}icefem run {} --resume {}",
            scene_path.display(),
            summary.output.display()
        );
        if let Some(t) = options.end_time {
            again += &format!(" --end-time {t}");
        }
        if let Some(dt) = options.dt {
            again += &format!(" --dt {dt}");
        }
        eprintln!("resume with: {again}");
    }
    Ok(summary)
}

/// Exit code 130 for a run stopped by a signal (after the processes' last MPI calls).
fn exit_if_interrupted(summary: &icefem::run::RunSummary) {
    if summary.interrupted {
        std::process::exit(130);
    }
}
