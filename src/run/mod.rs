//! A whole run: scene → simulation → HDF5 frames, with resume and clean interruption.

mod fracture_parts;
mod frame;
mod outcome;
mod restore;
mod surfaces;

pub use fracture_parts::{CrackTotals, FractureOnParts, FracturePart, ResumedSplit, CRACK_ROW};
pub use outcome::{FractureOutcome, Outcome};

use crate::fracture::{Fracture, FractureReport, FractureSettings};
use crate::output::{
    BackgroundWriter, FrameHead, FrameOptions, HeaderMesh, ObstacleMesh, OutputError, OutputWriter,
    ResumeFrame, RunHeader, StepStats,
};
use crate::physics::contact::Shape;
use crate::physics::Model;
use crate::scene::{Scene, SceneError};
use crate::sim::part::Part;
use crate::sim::{SimError, Simulation, StepReport, StepSettings};
use crate::thermal::{Heat, HeatLink};
use frame::{emit_frame, FrameFlags, SharedFrame};
use restore::{restore, resumed_on_parts, resumed_part};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};

/// Errors of a run.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    /// The scene is invalid.
    #[error(transparent)]
    Scene(#[from] SceneError),
    /// Set-up or a step failed.
    #[error(transparent)]
    Sim(#[from] SimError),
    /// Output failed.
    #[error(transparent)]
    Output(#[from] OutputError),
    /// The scene's problem cannot be set up (e.g. a Dirichlet region that holds no node).
    #[error("{}: {error}", path.display())]
    Setup {
        /// The scene file.
        path: PathBuf,
        /// What is wrong.
        error: SimError,
    },
    /// The file to resume does not belong to this scene or mesh.
    #[error("cannot resume {path}: {reason}")]
    Resume { path: PathBuf, reason: String },
}

/// Options of a run besides the scene.
#[derive(Clone, Debug, Default)]
pub struct RunOptions {
    /// Output file; default from the scene.
    pub output: Option<PathBuf>,
    /// Override of the end time (s).
    pub end_time: Option<f64>,
    /// Override of the time step (s).
    pub dt: Option<f64>,
    /// Continue this file from its last complete frame instead of starting anew.
    pub resume: bool,
    /// Replace an existing icefem output file (never another kind of file, nor a file another
    /// run is writing); without it an existing output is an error.
    pub force: bool,
}

/// What a finished (or interrupted) run did.
#[derive(Clone, Debug, Default)]
pub struct RunSummary {
    /// The output file.
    pub output: PathBuf,
    /// Steps taken in this invocation.
    pub steps: u64,
    /// Step reached (counting resumed steps).
    pub final_step: u64,
    /// Time reached (s).
    pub final_time: f64,
    /// Frames in the file.
    pub frames: usize,
    /// Newton iterations in this invocation.
    pub newton_iterations: u64,
    /// Largest final Newton residual of any step (N).
    pub max_residual: f64,
    /// Whether the run stopped early because it was interrupted.
    pub interrupted: bool,
    /// Times the processes gathered their ghost surfaces again (see
    /// `distributed::surface_hold`) in this invocation: because the ice moved past what they
    /// held, and in all (also at restart points); and the time that took (s).
    pub surface_gatherings: (u64, u64, f64),
    /// What happened physically (on one process, or where every process holds the whole
    /// mesh; for a run shared among parts, its fracture only).
    pub outcome: Outcome,
}

/// Progress reported after every step.
pub struct Progress<'a> {
    /// Step just completed.
    pub step: u64,
    /// Total steps of the run.
    pub total_steps: u64,
    /// Time reached (s).
    pub time: f64,
    /// Time the run ends at (s).
    pub end_time: f64,
    /// The step's report.
    pub report: &'a StepReport,
}

/// Number of steps to reach `end_time` with steps of `dt` (a last partial step is not taken;
/// a hair's round-off below a whole number counts as whole).
pub fn step_count(end_time: f64, dt: f64) -> u64 {
    (end_time / dt + 1e-9).floor() as u64
}

/// The processes a run is shared among (see `distributed`): every process runs [`run_on`]
/// with the same scene and options and takes the same steps; one writes the output.
pub trait Processes {
    /// This process's part of `model` and its model (see `sim::part`): the whole mesh if
    /// `whole`, else its elements, those around their nodes and, with ice–ice contact, those
    /// of its ghost surface for steps of `h` seconds (see `distributed::surface_hold`).
    fn part_model(
        &self,
        model: &Model,
        whole_and_h: (bool, f64),
    ) -> Result<(Part, Model), SimError>;
    /// Whether the ghost surface this process's `part` holds for the ice–ice contact of `sim`
    /// no longer holds what its next step needs: alike on every process, which all call it
    /// (never, without one).
    fn surface_outgrown(&self, _sim: &Simulation, _part: &Part) -> bool {
        false
    }
    /// This process's part of `model` (the whole model) again, and its model, with its ghost
    /// surface gathered at the state of `sim` on `part`: its own elements and owned nodes stay.
    /// Every process calls it.
    fn regathered(
        &self,
        _model: &Model,
        _sim: &Simulation,
        _part: &Part,
    ) -> Result<(Part, Model), SimError> {
        Err(SimError::Setup(
            "these processes hold no ghost surface".into(),
        ))
    }
    /// Fracture with `settings` of `sim`, built on this process's `part` of the scene's mesh
    /// and shared among the processes (see [`FractureOnParts`]). Every process calls it.
    fn part_fracture(
        &self,
        _settings: FractureSettings,
        _sim: &mut Simulation,
        _part: &Part,
    ) -> Result<Box<dyn FractureOnParts + '_>, SimError> {
        Err(SimError::NotDistributed("fracture on the processes' parts"))
    }
    /// The processes building a scene on their parts of its mesh (see
    /// [`crate::scene::MeshSharing`]), if they do.
    fn mesh_sharing(&self) -> Option<&dyn crate::scene::MeshSharing> {
        None
    }
    /// Shares `sim`, built on [`Processes::part_model`] (or on the part a scene was built on),
    /// among the processes before its first step.
    fn distribute(&self, sim: &mut Simulation) -> Result<(), SimError>;
    /// Number of processes.
    fn count(&self) -> usize;
    /// Whether this process writes the output file.
    fn writes(&self) -> bool;
    /// Whether `flag` is set on any process (every process must stop at the same step).
    fn any(&self, flag: bool) -> bool;
    /// The bytes the writing process gives, on every process (the others give none).
    fn broadcast_bytes(&self, bytes: Vec<u8>) -> Vec<u8>;
    /// Every process's `values`, in process order, given to `take` on the writing process
    /// one at a time (it holds one other process's values at once); nothing elsewhere.
    fn gather_values(&self, values: Vec<f64>, take: &mut dyn FnMut(Vec<f64>));
}

/// Runs `scene` with `options`, calling `progress` after every step; stops early (cleanly, with
/// the last state written) once `interrupt` is set.
pub fn run(
    scene: &Scene,
    options: &RunOptions,
    interrupt: &AtomicBool,
    progress: impl FnMut(&Progress),
) -> Result<RunSummary, RunError> {
    run_on(scene.clone(), options, None, interrupt, progress)
}

/// [`run`], shared among `processes` if given; resuming, the writing process reads the frame
/// and gives it to the others (a block of rows at a time, each process keeping its part's,
/// where the processes hold parts). The scene (its whole model) is let go once the run is set up:
/// the simulation holds what it needs (in a distributed run, this process's part).
pub fn run_on(
    whole: Scene,
    options: &RunOptions,
    processes: Option<&dyn Processes>,
    interrupt: &AtomicBool,
    progress: impl FnMut(&Progress),
) -> Result<RunSummary, RunError> {
    let scene = &whole;
    let (settings, end_time) = checked_times(scene, options)?;
    let output = options
        .output
        .clone()
        .unwrap_or_else(|| scene.output.clone());
    let (mut sim, part) = simulation_for(scene, settings, processes)?;
    // The processes' parts, where they are not the whole mesh.
    let shared = processes
        .zip(part.as_ref())
        .filter(|(_, part)| !part.is_whole());
    // Fracture on the processes' parts where they hold parts, else on the mesh held.
    let mut on_parts = match (shared, scene.fracture) {
        (Some((processes, part)), Some(f)) => Some(
            (processes.part_fracture(f, &mut sim, part)).map_err(|error| RunError::Setup {
                path: scene.path.clone(),
                error,
            })?,
        ),
        _ => None,
    };
    let mut fracture = (scene.fracture)
        .filter(|_| on_parts.is_none())
        .map(|f| Fracture::new(f, &sim.model.mesh));
    let writes = processes.is_none_or(|p| p.writes());
    let writer = if options.resume {
        match (shared, on_parts.take()) {
            // Each process reads its part's rows of the frame, a block at a time.
            (Some((processes, part)), fracture) => {
                let (writer, head) = read_for_resume(
                    (scene, &output),
                    (Some(processes), processes.writes()),
                    || OutputWriter::resume_head(&output, end_time),
                    (FrameHead::to_bytes, FrameHead::from_bytes),
                )?;
                let reading = (processes, writer.as_ref(), output.as_path());
                match fracture {
                    // Fracture on the parts: the frame's split mesh shared out as it splits.
                    Some(fracture) => {
                        let resumed =
                            resumed_on_parts((reading, scene, head), (part, sim, fracture))?;
                        (sim, on_parts) = (resumed.0, Some(resumed.1));
                    }
                    None => {
                        let frame = resumed_part(
                            processes,
                            (writer.as_ref(), &output),
                            (head, restore::BLOCK_VALUES),
                            (part, &sim.model.mesh),
                        )?;
                        restore(&mut sim, None, &output, &frame, &scene.text)?;
                    }
                }
                writer
            }
            (None, _) => {
                let (writer, frame) = read_for_resume(
                    (scene, &output),
                    (processes, writes),
                    || OutputWriter::resume_until(&output, end_time),
                    (ResumeFrame::to_bytes, ResumeFrame::from_bytes),
                )?;
                restore(&mut sim, fracture.as_mut(), &output, &frame, &scene.text)?;
                writer
            }
        }
    } else {
        // Where the processes hold parts, the writing process gets the header's mesh from
        // them in blocks, as it gets frames.
        let rest = match (shared, writes) {
            (None, true) => rows(&scene.model.mesh.rest),
            _ => Vec::new(),
        };
        let mesh = match shared {
            Some((_, part)) => HeaderMesh::InBlocks {
                nodes: part.whole_nodes(),
                elements: part.whole_elements(),
            },
            None => HeaderMesh::Whole {
                rest_positions: &rest,
                tets: &scene.model.mesh.tets,
            },
        };
        let mut writer = match writes {
            true => Some(new_writer(scene, options, &output, mesh)?),
            false => None,
        };
        if let Some((processes, part)) = shared {
            frame::write_mesh_in_blocks(writer.as_mut(), processes, part, &sim.model.mesh)?;
        }
        writer
    };
    let shared = processes.zip(part).filter(|(_, part)| !part.is_whole());
    // Processes holding ghost surfaces gather them again from the whole model as the ice
    // moves (fracture on the parts holds its own); other runs let it go.
    let surface = shared.is_some() && scene.model.ice_contact().is_some() && on_parts.is_none();
    let mut run = Run {
        frames: (scene.frame_options, scene.output_every, scene.restart_every),
        settings,
        end_time,
        processes,
        shared,
        whole: surface.then_some(whole),
        sim,
        fracture,
        on_parts,
        writer: writer.map(BackgroundWriter::start),
        output,
    };
    if !options.resume {
        run.emit_frame(FrameFlags {
            topology_changed: true,
            restart_point: true,
        })?;
    }
    run.steps(interrupt, progress)
}

/// The scene's step settings with `--dt`, and the end time (s) with `--end-time`, checked.
fn checked_times(scene: &Scene, options: &RunOptions) -> Result<(StepSettings, f64), RunError> {
    let invalid = |field: &str, value: f64| {
        RunError::Scene(SceneError::Invalid {
            path: scene.path.clone(),
            field: field.into(),
            message: format!("must be finite and > 0, got {value}"),
        })
    };
    let mut settings = scene.settings;
    if let Some(dt) = options.dt {
        if !(dt.is_finite() && dt > 0.0) {
            return Err(invalid("--dt", dt));
        }
        settings.dt = dt;
    }
    let end_time = options.end_time.unwrap_or(scene.end_time);
    if !(end_time.is_finite() && end_time > 0.0) {
        return Err(invalid("--end-time", end_time));
    }
    Ok((settings, end_time))
}

/// The simulation of `scene` (this process's part of it, shared among `processes` if given)
/// with the heat model of `[thermal]` attached; the process's part, in a shared run.
fn simulation_for(
    scene: &Scene,
    settings: StepSettings,
    processes: Option<&dyn Processes>,
) -> Result<(Simulation, Option<Part>), RunError> {
    let setup = |error| RunError::Setup {
        path: scene.path.clone(),
        error,
    };
    let (mut sim, part) =
        match processes {
            None if scene.part.is_some() => return Err(setup(SimError::Setup(
                "the scene was built on a process's part of its mesh: run it with its processes"
                    .into(),
            ))),
            None => (
                Simulation::new(scene.model.clone(), settings).map_err(setup)?,
                None,
            ),
            Some(processes) => {
                let (part, model) = match &scene.part {
                    // Built on this process's part: its checks are the processes' together.
                    Some(part) => {
                        Simulation::check_shared(&scene.model, &settings, &|f| processes.any(f))
                            .map_err(setup)?;
                        (part.clone(), scene.model.clone())
                    }
                    None => {
                        Simulation::check(&scene.model, &settings).map_err(setup)?;
                        (processes.part_model(&scene.model, (false, settings.dt))).map_err(setup)?
                    }
                };
                (
                    Simulation::for_part(model, settings).map_err(setup)?,
                    Some(part),
                )
            }
        };
    attach_heat(scene, &mut sim, part.as_ref())?;
    if let Some(processes) = processes {
        processes.distribute(&mut sim).map_err(setup)?;
    }
    Ok((sim, part))
}

/// Attaches the heat model of `scene`'s `[thermal]` (if any) to `sim`, on this process's
/// `part` in a shared run.
fn attach_heat(scene: &Scene, sim: &mut Simulation, part: Option<&Part>) -> Result<(), RunError> {
    if let Some(thermal) = &scene.thermal {
        // On the scene's mesh, before a resumed fractured run rebuilds its split mesh, or on
        // this process's part of it (with the whole masses: a process's part of a
        // distributed run has those of its owned nodes only).
        let mesh = &sim.model.mesh;
        let (mass, boundary, initial) = match part.filter(|_| scene.part.is_none()) {
            Some(part) => (
                part.rows_of(&thermal.mass, 1, false),
                thermal.boundary.restricted(|i| part.local(i)),
                part.rows_of(&thermal.initial, 1, false),
            ),
            // The whole mesh, or the part the scene was built on.
            None => (
                thermal.mass.clone(),
                thermal.boundary.clone(),
                thermal.initial.clone(),
            ),
        };
        let heat = Heat::new(mesh, mass, thermal.phases, &boundary, initial).map_err(|e| {
            RunError::Setup {
                path: scene.path.clone(),
                error: e.into(),
            }
        })?;
        let link = HeatLink::new(heat, mesh);
        sim.attach_heat(link);
    }
    Ok(())
}

/// How what process 0 reads when a run resumes travels to the other processes: as bytes, and
/// back (`None`: the bytes are not one).
type AsBytes<T> = (fn(&T) -> Vec<u8>, fn(&[u8]) -> Option<T>);

/// What the writing process (`writes`) reads of the file `output` a run resumes with `read`
/// (the last complete frame, or its head), given to the other processes as bytes
/// (`to_bytes`, `from_bytes`), and the file's writer on the writing process.
fn read_for_resume<T>(
    (scene, output): (&Scene, &Path),
    (processes, writes): (Option<&dyn Processes>, bool),
    read: impl FnOnce() -> Result<(OutputWriter, T), OutputError>,
    (to_bytes, from_bytes): AsBytes<T>,
) -> Result<(Option<OutputWriter>, T), RunError> {
    if writes {
        let (mut writer, read) = read()?;
        writer.set_frame_options(scene.frame_options);
        if let Some(processes) = processes {
            processes.broadcast_bytes(to_bytes(&read));
        }
        return Ok((Some(writer), read));
    }
    let bytes = processes.map_or(Vec::new(), |p| p.broadcast_bytes(Vec::new()));
    let read = from_bytes(&bytes).ok_or_else(|| RunError::Resume {
        path: output.into(),
        reason: "what process 0 read of the frame did not arrive whole".into(),
    })?;
    Ok((None, read))
}

/// A new output file `output` for `scene` (replacing an icefem file with `--force`), its
/// header written, with the initial `mesh`.
fn new_writer(
    scene: &Scene,
    options: &RunOptions,
    output: &Path,
    mesh: HeaderMesh,
) -> Result<OutputWriter, RunError> {
    let obstacles = obstacle_meshes(&scene.model);
    let scene_path = absolute(&scene.path);
    let header = RunHeader {
        scene_text: &scene.text,
        scene_path: &scene_path.to_string_lossy(),
        version: env!("CARGO_PKG_VERSION"),
        mesh,
        obstacles: &obstacles,
    };
    let mut writer = if options.force {
        OutputWriter::replace(output, &header)?
    } else {
        OutputWriter::create(output, &header)?
    };
    writer.set_frame_options(scene.frame_options);
    Ok(writer)
}

/// A run set up: its simulation, fracture and output, stepped to the end time.
struct Run<'a> {
    /// What the frames store, and every how many steps frames and restart points come.
    frames: (FrameOptions, u64, u64),
    settings: StepSettings,
    /// End time (s).
    end_time: f64,
    processes: Option<&'a dyn Processes>,
    /// The processes and this one's part, where the parts are not the whole mesh (with
    /// fracture on the parts, the part the run started on: `on_parts` holds the current one).
    shared: Option<(&'a dyn Processes, Part)>,
    /// The scene, where the processes' parts hold ghost surfaces for ice–ice contact, which
    /// they gather again from its whole model as the ice moves.
    whole: Option<Scene>,
    sim: Simulation,
    /// Fracture, where it splits the mesh the process holds (the whole mesh).
    fracture: Option<Fracture>,
    /// Fracture on the processes' parts.
    on_parts: Option<Box<dyn FractureOnParts + 'a>>,
    /// The output (on the writing process).
    writer: Option<BackgroundWriter>,
    output: PathBuf,
}

impl Run<'_> {
    /// Writes the current state as a frame (gathered onto the writing process).
    fn emit_frame(&mut self, flags: FrameFlags) -> Result<(), RunError> {
        let sim_and_fracture = (&self.sim, self.fracture.as_ref());
        let options = self.frames.0;
        emit_frame(
            self.writer.as_mut(),
            sim_and_fracture,
            shared_frame(&self.shared, &self.on_parts),
            (flags, options),
        )
    }

    /// Whether an interrupt is set on any process (every process stops at the same step).
    fn interrupted(&self, interrupt: &AtomicBool) -> bool {
        let interrupted = interrupt.load(Ordering::SeqCst);
        self.processes.map_or(interrupted, |p| p.any(interrupted))
    }

    /// Steps from the state reached (a resumed file's last frame, possibly written with
    /// another dt) to the last whole step not past the end time, writing the frames due;
    /// stops after a step once `interrupt` is set.
    fn steps(
        mut self,
        interrupt: &AtomicBool,
        mut progress: impl FnMut(&Progress),
    ) -> Result<RunSummary, RunError> {
        let (end_time, dt) = (self.end_time, self.settings.dt);
        let remaining = end_time - self.sim.state.time;
        if remaining < -1e-9 * end_time {
            return Err(RunError::Resume {
                path: self.output.clone(),
                reason: format!(
                    "it already reaches t = {} s (step {}), past the end time {end_time} s; give a later --end-time",
                    self.sim.state.time, self.sim.state.step
                ),
            });
        }
        let mut total_steps = self.sim.state.step + step_count(remaining.max(0.0), dt);
        let mut summary = RunSummary {
            output: self.output.clone(),
            ..Default::default()
        };
        // Whether the mesh changed since the last frame written.
        let mut topology_changed = false;
        // Whether the last step ended on a restart point (the surfaces held for ice–ice
        // contact were gathered at the start of this invocation).
        let mut restarted = false;
        let settings = (self.fracture.as_ref().map(|f| f.settings))
            .or(self.on_parts.as_ref().map(|f| f.settings()));
        let mut fracture_outcome = settings.map(|f| FractureOutcome {
            toughness: f.toughness,
            yield_stress: self
                .sim
                .model
                .elasticity
                .plasticity
                .map(|p| 2.0 * self.sim.model.elasticity.material.mu * p.elastic_limit),
            ..Default::default()
        });
        while self.time_left(total_steps) {
            if self.interrupted(interrupt) {
                summary.interrupted = true;
                break;
            }
            if let Some((outgrown, seconds)) = self.hold_surfaces(restarted)? {
                let g = &mut summary.surface_gatherings;
                *g = (g.0 + u64::from(outgrown), g.1 + 1, g.2 + seconds);
            }
            let (report, cracked, due) = self.step(&mut total_steps)?;
            topology_changed |= !cracked.events.is_empty();
            if let Some(f) = &mut fracture_outcome {
                f.add_step(cracked.largest_stress, cracked.events.len());
            }
            summary.steps += 1;
            summary.newton_iterations += report.newton.iterations as u64;
            summary.max_residual = summary.max_residual.max(report.newton.residual);
            // The whole mesh's elements and cracks (a process's part of a distributed run
            // holds only some).
            let elements = match shared_frame(&self.shared, &self.on_parts) {
                Some((_, part, _)) => part.whole_elements(),
                None => self.sim.model.mesh.num_tets(),
            };
            let cracks = match (&self.on_parts, &self.fracture) {
                (Some(f), _) => Some(f.crack_totals()),
                (None, Some(f)) => {
                    let rest = &self.sim.model.mesh.rest;
                    Some(CrackTotals {
                        faces: f.faces.len() as u64,
                        area: f.crack_area(rest),
                        polygons: f.crack_polygons(rest) as u64,
                    })
                }
                (None, None) => None,
            };
            if let Some(writer) = &mut self.writer {
                let row = stats_row((&self.sim, elements), &report, &cracked, cracks);
                writer.append_stats(&row)?;
            }
            // Alike on every process: an interrupt on one stops them all after this step.
            let stopping = self.interrupted(interrupt);
            if due.frame || stopping {
                self.emit_frame(FrameFlags {
                    topology_changed,
                    restart_point: due.restart,
                })?;
                topology_changed = false;
            }
            // A run resumed from a frame here starts without solver memory: so does this one,
            // whether or not it writes a frame here, so that the frames written never change
            // the results.
            if due.restart {
                self.sim.forget_solver_memory();
            }
            restarted = due.restart;
            progress(&Progress {
                step: self.sim.state.step,
                total_steps,
                time: self.sim.state.time,
                end_time,
                report: &report,
            });
        }
        summary.final_step = self.sim.state.step;
        summary.final_time = self.sim.state.time;
        if let Some(outcome) = &mut fracture_outcome {
            match (&self.on_parts, &self.fracture) {
                // Every process's, from the sums over the parts.
                (Some(on_parts), _) => outcome.crack_area = on_parts.crack_totals().area,
                (None, Some(fracture)) => {
                    outcome.crack_area = fracture.crack_area(&self.sim.model.mesh.rest)
                }
                (None, None) => {}
            }
        }
        summary.outcome = Outcome::at_end(&self.sim, fracture_outcome);
        if let Some(writer) = self.writer {
            summary.frames = writer.frame_count();
            writer.finish()?;
        }
        Ok(summary)
    }

    /// Whether a step is left before the end: by time with adaptive steps, else by count.
    fn time_left(&self, total_steps: u64) -> bool {
        match self.settings.adaptive {
            Some(_) => self.end_time - self.sim.state.time > 1e-9 * self.end_time,
            None => self.sim.state.step < total_steps,
        }
    }

    /// The length of the interval between frames (s): `output_every` steps of the scene's
    /// dt. Adaptive steps end on the frame times.
    fn frame_interval(&self) -> f64 {
        self.frames.1 as f64 * self.settings.dt
    }

    /// One step and fracture's splits after it; whether a frame is due after it. With
    /// adaptive steps, `total_steps` is updated to the time left as steps of the current
    /// length (for progress).
    fn step(
        &mut self,
        total_steps: &mut u64,
    ) -> Result<(StepReport, FractureReport, FrameDue), RunError> {
        let frame_interval = self.frame_interval();
        let frame_index = |t: f64| (t / frame_interval + 1e-9).floor();
        // Adaptive steps end on the next frame time (or the end).
        let next_frame = (frame_index(self.sim.state.time) + 1.0) * frame_interval;
        let limit = next_frame.min(self.end_time);
        let sim = &mut self.sim;
        let report = match self.settings.adaptive {
            Some(_) => sim.step_adaptive(limit)?,
            None => sim.step()?,
        };
        let cracked = match (&mut self.fracture, &mut self.on_parts) {
            (Some(f), _) => f.after_step(sim)?,
            (None, Some(f)) => f.after_step(sim)?,
            (None, None) => FractureReport::default(),
        };
        // Restart points are steps every run through this time takes, wherever it ends: on
        // their own grid of steps, or (adaptive steps, which end on the frame times) on the
        // output grid.
        let due = match self.settings.adaptive {
            Some(_) => {
                // The step (or fracture's retake of it) ended on `limit` to round-off: it is
                // `limit`.
                if (sim.state.time - limit).abs() <= 1e-9 * frame_interval {
                    sim.state.time = limit;
                }
                // The time left as steps of the current length (for progress).
                let steps_left = (self.end_time - sim.state.time) / sim.state.next_dt.max(1e-300);
                *total_steps = sim.state.step + steps_left.max(0.0).ceil() as u64;
                let on_grid = sim.state.time == next_frame;
                let end = self.end_time - sim.state.time <= 1e-9 * self.end_time;
                FrameDue {
                    restart: on_grid,
                    frame: on_grid || end,
                }
            }
            None => {
                let step = sim.state.step;
                FrameDue {
                    restart: step.is_multiple_of(self.frames.2),
                    frame: step.is_multiple_of(self.frames.1) || step == *total_steps,
                }
            }
        };
        Ok((report, cracked, due))
    }
}

/// What this process gives to a frame where the processes hold parts (`shared`), with
/// fracture on the parts (`on_parts`).
fn shared_frame<'b>(
    shared: &'b Option<(&dyn Processes, Part)>,
    on_parts: &'b Option<Box<dyn FractureOnParts + '_>>,
) -> Option<SharedFrame<'b>> {
    let (processes, part) = shared.as_ref()?;
    Some(match on_parts {
        Some(f) => (*processes, f.part(), Some(&**f)),
        None => (*processes, part, None),
    })
}

/// Whether a frame is due after a step.
struct FrameDue {
    /// The step is a restart point: the solver forgets its memory after it, and a frame
    /// written there is one `--resume` continues from.
    restart: bool,
    /// A frame is written: on the output grid, or at the end.
    frame: bool,
}

/// The `/stats` row of the step `report` of `sim`, whose mesh has `elements` elements in
/// all, and its fracture's: what the step `cracked`, and the `cracks` after it.
fn stats_row(
    (sim, elements): (&Simulation, usize),
    report: &StepReport,
    cracked: &FractureReport,
    cracks: Option<CrackTotals>,
) -> StepStats {
    let cracks = cracks.unwrap_or_default();
    let n = &report.newton;
    StepStats {
        step: sim.state.step,
        time: sim.state.time,
        dt: sim.settings.dt,
        newton_iterations: n.iterations as u32,
        newton_solves: report.newton_solves,
        linear_iterations: n.linear_iterations as u32,
        factorizations: n.factorizations as u32,
        projections: n.projections as u32,
        substeps: report.substeps,
        residual: n.residual,
        energy: report.energies.total(),
        kinetic_energy: report.energies.kinetic,
        elastic_energy: report.energies.elastic,
        potential_energy: report.energies.potential,
        contact_energy: report.energies.contact,
        t_assembly: n.t_assembly,
        t_factorization: n.t_factorization,
        t_solve: n.t_solve,
        t_step: report.t_step,
        elements: elements as u64,
        crack_faces: cracks.faces,
        fracture_events: cracked.events.len() as u32,
        separation_stress: cracked.largest_stress,
        eligible_nodes: cracked.eligible_nodes as u64,
        nodes_above_toughness: cracked.nodes_above as u64,
        refused_nodes: cracked.refused_above as u64,
        refused_splits: cracked.refused as u32,
        crack_area: cracks.area,
        crack_polygons: cracks.polygons,
        t_fracture: cracked.t_check + cracked.t_split,
        t_remesh: cracked.t_remesh,
        t_resolve: cracked.t_resolve,
        heat_newton_iterations: report.heat.map_or(0, |h| h.newton_iterations as u32),
        heat_imbalance: report.heat.map_or(0.0, |h| h.imbalance()),
        heat_passes: report.heat.map_or(0, |h| h.passes as u32),
        heat_cancelled_edges: report.heat.map_or(0, |h| h.cancelled_edges as u64),
        t_heat: report.heat.map_or(0.0, |h| h.t_step),
        local_error: report.local_error,
        error_ratio: report.error_ratio,
        rejected_steps: report.rejected,
    }
}

/// `path` made absolute (symbolic links and `..` resolved where the file exists), so that the
/// file's `scene_path` names the scene from any folder.
fn absolute(path: &Path) -> PathBuf {
    std::fs::canonicalize(path)
        .or_else(|_| std::path::absolute(path))
        .unwrap_or_else(|_| path.to_path_buf())
}

/// The triangle surfaces of the scene's mesh obstacles at t = 0 (`[[obstacle]]` index, surface),
/// stored in the file so that pictures of it need not find the surface files.
fn obstacle_meshes(model: &Model) -> Vec<ObstacleMesh> {
    let Some(contact) = model.obstacle_contact() else {
        return Vec::new();
    };
    contact
        .obstacles
        .iter()
        .enumerate()
        .filter_map(|(index, o)| match &o.shape {
            Shape::Mesh { surface } => Some(ObstacleMesh {
                index,
                vertices: rows(&surface.vertices),
                triangles: surface.triangles.clone(),
            }),
            _ => None,
        })
        .collect()
}

fn rows(v: &[nalgebra::Vector3<f64>]) -> Vec<[f64; 3]> {
    v.iter().map(|p| [p.x, p.y, p.z]).collect()
}

fn as_rows(v: &[f64]) -> &[[f64; 3]] {
    // Plain reinterpretation of a flat 3n vector as n rows; lengths are multiples of 3 by
    // construction.
    let (rows, rest) = v.as_chunks::<3>();
    debug_assert!(rest.is_empty());
    rows
}
