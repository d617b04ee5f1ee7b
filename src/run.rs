//! A whole run: scene → simulation → HDF5 frames, with resume and clean interruption.

use crate::fem;
use crate::fracture::split::Fracturable;
use crate::fracture::{Fracture, FractureReport};
use crate::mesh::TetMesh;
use crate::output::{Field, Frame, ObstacleMesh, OutputError, OutputWriter, RunHeader, StepStats};
use crate::output::{ResumeFrame, StoredField};
use crate::physics::contact::ContactForces;
use crate::physics::contact::Shape;
use crate::physics::Model;
use crate::scene::{Scene, SceneError};
use crate::sim::part::{Part, StateShares};
use crate::sim::{SchemeState, SimError, Simulation, State, StepReport};
use crate::thermal::{Heat, HeatLink};
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
    /// `whole`, else its elements and those around their nodes.
    fn part_model(&self, model: &Model, whole: bool) -> Result<(Part, Model), SimError>;
    /// Shares `sim`, built on [`Processes::part_model`], among the processes before its
    /// first step.
    fn distribute(&self, sim: &mut Simulation) -> Result<(), SimError>;
    /// Number of processes.
    fn count(&self) -> usize;
    /// Whether this process writes the output file.
    fn writes(&self) -> bool;
    /// Whether `flag` is set on any process (every process must stop at the same step).
    fn any(&self, flag: bool) -> bool;
    /// The bytes the writing process gives, on every process (the others give none).
    fn broadcast_bytes(&self, bytes: Vec<u8>) -> Vec<u8>;
    /// Every process's `values`, in process order, on the writing process (none elsewhere).
    fn gather_values(&self, values: Vec<f64>) -> Vec<Vec<f64>>;
}

/// Runs `scene` with `options`, calling `progress` after every step; stops early (cleanly, with
/// the last state written) once `interrupt` is set.
pub fn run(
    scene: &Scene,
    options: &RunOptions,
    interrupt: &AtomicBool,
    progress: impl FnMut(&Progress),
) -> Result<RunSummary, RunError> {
    run_on(scene, options, None, interrupt, progress)
}

/// [`run`], shared among `processes` if given. A shared run refuses fracture (its remeshing
/// is not distributed); resuming, the writing process reads the frame and gives it to the
/// others.
pub fn run_on(
    scene: &Scene,
    options: &RunOptions,
    processes: Option<&dyn Processes>,
    interrupt: &AtomicBool,
    mut progress: impl FnMut(&Progress),
) -> Result<RunSummary, RunError> {
    if processes.is_some() && scene.fracture.is_some() {
        return Err(RunError::Setup {
            path: scene.path.clone(),
            error: SimError::NotDistributed(
                "fracture ([fracture]: its remeshing is not distributed)",
            ),
        });
    }
    let mut settings = scene.settings;
    if let Some(dt) = options.dt {
        if !(dt.is_finite() && dt > 0.0) {
            return Err(RunError::Scene(SceneError::Invalid {
                path: scene.path.clone(),
                field: "--dt".into(),
                message: format!("must be finite and > 0, got {dt}"),
            }));
        }
        settings.dt = dt;
    }
    let end_time = options.end_time.unwrap_or(scene.end_time);
    if !(end_time.is_finite() && end_time > 0.0) {
        return Err(RunError::Scene(SceneError::Invalid {
            path: scene.path.clone(),
            field: "--end-time".into(),
            message: format!("must be finite and > 0, got {end_time}"),
        }));
    }
    let output = options
        .output
        .clone()
        .unwrap_or_else(|| scene.output.clone());
    let setup = |error| RunError::Setup {
        path: scene.path.clone(),
        error,
    };
    let (mut sim, part) = match processes {
        None => (
            Simulation::new(scene.model.clone(), settings).map_err(setup)?,
            None,
        ),
        Some(processes) => {
            Simulation::check(&scene.model, &settings).map_err(setup)?;
            let (part, model) = processes
                .part_model(&scene.model, needs_whole_mesh(scene))
                .map_err(setup)?;
            (
                Simulation::for_part(model, settings).map_err(setup)?,
                Some(part),
            )
        }
    };
    // The processes' parts, where they are not the whole mesh.
    let shared = processes
        .zip(part.as_ref())
        .filter(|(_, part)| !part.is_whole());
    let mut fracture = scene.fracture.map(|f| Fracture::new(f, &sim.model.mesh));
    if let Some(setup) = &scene.thermal {
        // On the scene's mesh, before a resumed fractured run rebuilds its split mesh (with
        // the whole masses: a process's part of a distributed run has those of its nodes).
        let mesh = &sim.model.mesh;
        let heat = Heat::new(
            mesh,
            scene.model.mass.clone(),
            setup.phases,
            &setup.boundary,
            setup.initial.clone(),
        )
        .map_err(|e| RunError::Setup {
            path: scene.path.clone(),
            error: e.into(),
        })?;
        let link = HeatLink::new(heat, mesh);
        sim.attach_heat(link);
    }
    if let Some(processes) = processes {
        processes.distribute(&mut sim).map_err(setup)?;
    }
    let writes = processes.is_none_or(|p| p.writes());
    let mut writer = if options.resume {
        let (writer, frame) = if writes {
            let (mut writer, frame) = OutputWriter::resume_until(&output, end_time)?;
            writer.store_tensor_matrices(scene.tensor_matrices);
            if let Some(processes) = processes {
                processes.broadcast_bytes(frame.to_bytes());
            }
            (Some(writer), frame)
        } else {
            let bytes = processes.map_or(Vec::new(), |p| p.broadcast_bytes(Vec::new()));
            let frame =
                crate::output::ResumeFrame::from_bytes(&bytes).ok_or_else(|| RunError::Resume {
                    path: output.clone(),
                    reason: "the frame process 0 read did not arrive whole".into(),
                })?;
            (None, frame)
        };
        match shared {
            Some((_, part)) => {
                let mesh = &scene.model.mesh;
                if frame.rest_positions != rows(&mesh.rest) || frame.tets != mesh.tets {
                    return Err(RunError::Resume {
                        path: output.clone(),
                        reason: "its mesh differs from the scene's mesh".into(),
                    });
                }
                let frame = part_frame(part, &frame, mesh);
                restore(&mut sim, None, &output, &frame, &scene.text)?;
            }
            None => restore(&mut sim, fracture.as_mut(), &output, &frame, &scene.text)?,
        }
        writer
    } else if !writes {
        None
    } else {
        // The scene's mesh, which a process of a distributed run may hold a part of.
        let rest = rows(&scene.model.mesh.rest);
        let obstacles = obstacle_meshes(&scene.model);
        let scene_path = absolute(&scene.path);
        let header = RunHeader {
            scene_text: &scene.text,
            scene_path: &scene_path.to_string_lossy(),
            version: env!("CARGO_PKG_VERSION"),
            rest_positions: &rest,
            tets: &scene.model.mesh.tets,
            obstacles: &obstacles,
        };
        let mut writer = if options.force {
            OutputWriter::replace(&output, &header)?
        } else {
            OutputWriter::create(&output, &header)?
        };
        writer.store_tensor_matrices(scene.tensor_matrices);
        Some(writer)
    };
    if !options.resume {
        let shares = shared.map(|(p, part)| (p, part, &scene.model.mesh));
        emit_frame(
            writer.as_mut(),
            (&sim, fracture.as_ref()),
            shares,
            (true, true),
        )?;
    }
    // Steps from the state reached (a resumed file's last frame, possibly written with
    // another dt) to the last whole step not past the end time.
    let remaining = end_time - sim.state.time;
    if remaining < -1e-9 * end_time {
        return Err(RunError::Resume {
            path: output.clone(),
            reason: format!(
                "it already reaches t = {} s (step {}), past the end time {end_time} s; give a later --end-time",
                sim.state.time, sim.state.step
            ),
        });
    }
    let mut total_steps = sim.state.step + step_count(remaining.max(0.0), settings.dt);
    // Adaptive steps end on the frame times, every `output_every` steps of the scene's dt.
    let frame_interval = scene.output_every as f64 * settings.dt;
    let frame_index = |t: f64| (t / frame_interval + 1e-9).floor();
    let time_left = |t: f64| end_time - t > 1e-9 * end_time;
    let mut summary = RunSummary {
        output: output.clone(),
        ..Default::default()
    };
    // Whether the mesh changed since the last frame written.
    let mut topology_changed = false;
    loop {
        let more = match settings.adaptive {
            Some(_) => time_left(sim.state.time),
            None => sim.state.step < total_steps,
        };
        if !more {
            break;
        }
        let interrupted = interrupt.load(Ordering::SeqCst);
        if processes.map_or(interrupted, |p| p.any(interrupted)) {
            summary.interrupted = true;
            break;
        }
        // Adaptive steps end on the next frame time (or the end).
        let next_frame = (frame_index(sim.state.time) + 1.0) * frame_interval;
        let limit = next_frame.min(end_time);
        let report = match settings.adaptive {
            Some(_) => sim.step_adaptive(limit)?,
            None => sim.step()?,
        };
        let cracked = match &mut fracture {
            Some(f) => f.after_step(&mut sim)?,
            None => FractureReport::default(),
        };
        // A frame on the output grid is one every run through this time writes, wherever it
        // ends: a restart point.
        let on_grid;
        let frame_due = match settings.adaptive {
            Some(_) => {
                // The step (or fracture's retake of it) ended on `limit` to round-off: it is
                // `limit`.
                if (sim.state.time - limit).abs() <= 1e-9 * frame_interval {
                    sim.state.time = limit;
                }
                // The time left as steps of the current length (for progress).
                let steps_left = (end_time - sim.state.time) / sim.state.next_dt.max(1e-300);
                total_steps = sim.state.step + steps_left.max(0.0).ceil() as u64;
                on_grid = sim.state.time == next_frame;
                on_grid || !time_left(sim.state.time)
            }
            None => {
                on_grid = sim.state.step % scene.output_every == 0;
                on_grid || sim.state.step == total_steps
            }
        };
        topology_changed |= !cracked.events.is_empty();
        summary.steps += 1;
        summary.newton_iterations += report.newton.iterations as u64;
        summary.max_residual = summary.max_residual.max(report.newton.residual);
        if let Some(writer) = &mut writer {
            // A process's part of a distributed run holds only some of the elements.
            let elements = match shared {
                Some(_) => scene.model.mesh.num_tets(),
                None => sim.model.mesh.num_tets(),
            };
            let row = stats_row((&sim, elements), &report, &cracked, fracture.as_ref());
            writer.append_stats(&row)?;
        }
        // Alike on every process: an interrupt on one stops them all after this step.
        let stopping = interrupt.load(Ordering::SeqCst);
        let stopping = processes.map_or(stopping, |p| p.any(stopping));
        if frame_due || stopping {
            let shares = shared.map(|(p, part)| (p, part, &scene.model.mesh));
            let flags = (topology_changed, on_grid);
            emit_frame(writer.as_mut(), (&sim, fracture.as_ref()), shares, flags)?;
            topology_changed = false;
            // A run resumed from this frame starts without solver memory: so does this one.
            if on_grid {
                sim.forget_solver_memory();
            }
        }
        progress(&Progress {
            step: sim.state.step,
            total_steps,
            time: sim.state.time,
            end_time,
            report: &report,
        });
    }
    summary.final_step = sim.state.step;
    summary.final_time = sim.state.time;
    if let Some(writer) = writer {
        summary.frames = writer.frame_count();
        writer.finish()?;
    }
    Ok(summary)
}

fn stats_row(
    (sim, elements): (&Simulation, usize),
    report: &StepReport,
    cracked: &FractureReport,
    fracture: Option<&Fracture>,
) -> StepStats {
    let n = &report.newton;
    StepStats {
        step: sim.state.step,
        time: sim.state.time,
        dt: sim.settings.dt,
        newton_iterations: n.iterations as u32,
        newton_solves: report.newton_solves,
        linear_iterations: n.linear_iterations as u32,
        factorizations: n.factorizations as u32,
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
        crack_faces: fracture.map_or(0, |f| f.faces.len() as u64),
        fracture_events: cracked.events.len() as u32,
        separation_stress: cracked.largest_stress,
        eligible_nodes: cracked.eligible_nodes as u64,
        nodes_above_toughness: cracked.nodes_above as u64,
        refused_nodes: cracked.refused_above as u64,
        refused_splits: cracked.refused as u32,
        crack_area: fracture.map_or(0.0, |f| f.crack_area(&sim.model.mesh.rest)),
        crack_polygons: fracture.map_or(0, |f| f.crack_polygons(&sim.model.mesh.rest) as u64),
        t_fracture: cracked.t_check + cracked.t_split,
        t_remesh: cracked.t_remesh,
        t_resolve: cracked.t_resolve,
        heat_newton_iterations: report.heat.map_or(0, |h| h.newton_iterations as u32),
        heat_imbalance: report.heat.map_or(0.0, |h| h.imbalance()),
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

/// Whether a distributed run needs the whole mesh on every process: where a term couples
/// nodes beyond their elements (ice–ice contact, Rayleigh's β K) or the heat equation is
/// solved (on the whole mesh).
fn needs_whole_mesh(scene: &Scene) -> bool {
    let model = &scene.model;
    scene.thermal.is_some()
        || model.ice_contact().is_some()
        || model.damping.is_some_and(|d| d.stiffness > 0.0)
}

/// Writes the current state of `sim` as a frame on the writing process (`writer`). In a
/// distributed run whose processes hold parts of the mesh (`shared`: the processes, this
/// one's part, the whole mesh), every process first gives its part of the state to the
/// writing one.
fn emit_frame(
    writer: Option<&mut OutputWriter>,
    (sim, fracture): (&Simulation, Option<&Fracture>),
    shared: Option<(&dyn Processes, &Part, &TetMesh)>,
    flags: (bool, bool),
) -> Result<(), RunError> {
    let Some((processes, part, mesh)) = shared else {
        if let Some(writer) = writer {
            write_frame(
                writer,
                &FrameSource::of(sim),
                fracture.map(|f| (f, sim)),
                flags,
            )?;
        }
        return Ok(());
    };
    let contact = sim.contact_forces();
    let share = part.share_of(
        &sim.state,
        &sim.stresses(),
        contact.unwrap_or(&ContactForces::default()),
    );
    let shares = processes.gather_values(share);
    let Some(writer) = writer else {
        return Ok(());
    };
    let whole = StateShares::whole(
        &shares,
        mesh.num_nodes(),
        mesh.num_tets(),
        (
            sim.integrator().carried_fields(),
            sim.integrator().carried_scalars(),
        ),
    )
    .ok_or_else(|| SimError::Setup("a process's part of the state did not arrive whole".into()))?;
    let state = State {
        time: sim.state.time,
        step: sim.state.step,
        next_dt: sim.state.next_dt,
        ..whole.state
    };
    let source = FrameSource {
        mesh,
        state: &state,
        stress: whole.stress,
        contact: contact.map(|_| &whole.contact),
        temperature: None,
    };
    Ok(write_frame(writer, &source, None, flags)?)
}

/// The part `part` of a frame of the whole mesh `mesh` (checked to be the frame's): its nodes'
/// and elements' rows, its elements numbered in the part.
fn part_frame(part: &Part, frame: &ResumeFrame, mesh: &TetMesh) -> ResumeFrame {
    let pick = |rows: &[[f64; 3]]| part.nodes.iter().map(|&i| rows[i]).collect();
    let fields = |fields: &[StoredField], count: usize, per_element: bool| {
        fields
            .iter()
            .filter(|f| f.data.len() == f.columns * count)
            .map(|f| StoredField {
                name: f.name.clone(),
                columns: f.columns,
                data: part.rows_of(&f.data, f.columns, per_element),
            })
            .collect()
    };
    ResumeFrame {
        step: frame.step,
        time: frame.time,
        scene_text: frame.scene_text.clone(),
        positions: pick(&frame.positions),
        velocities: pick(&frame.velocities),
        rest_positions: pick(&frame.rest_positions),
        tets: part.tets_of(&mesh.tets),
        element_fields: fields(&frame.element_fields, mesh.num_tets(), true),
        node_fields: fields(&frame.node_fields, mesh.num_nodes(), false),
        attributes: frame.attributes.clone(),
    }
}

/// What a frame is written from: a simulation's mesh and state, or the whole state of a
/// distributed run put together from the processes' parts.
struct FrameSource<'a> {
    mesh: &'a TetMesh,
    state: &'a State,
    /// Element stresses (Pa, Voigt).
    stress: Vec<[f64; 6]>,
    /// Contact forces, if the model has contact.
    contact: Option<&'a ContactForces>,
    /// Temperature of every node (°C), with `[thermal]`.
    temperature: Option<Vec<f64>>,
}

impl<'a> FrameSource<'a> {
    /// The simulation's current state.
    fn of(sim: &'a Simulation) -> Self {
        FrameSource {
            mesh: &sim.model.mesh,
            state: &sim.state,
            stress: sim.stresses(),
            contact: sim.contact_forces(),
            temperature: sim.node_temperatures(),
        }
    }
}

/// Writes the current state as a frame; `restart_point` marks a frame on the output grid,
/// after which the run forgets its solver memory (see [`Simulation::forget_solver_memory`]):
/// `--resume` continues from the last such frame.
fn write_frame(
    writer: &mut OutputWriter,
    source: &FrameSource,
    fracture: Option<(&Fracture, &Simulation)>,
    (topology_changed, restart_point): (bool, bool),
) -> Result<(), OutputError> {
    let state = source.state;
    let rest = rows(&source.mesh.rest);
    let positions: Vec<[f64; 3]> = source
        .mesh
        .rest
        .iter()
        .enumerate()
        .map(|(i, p)| std::array::from_fn(|a| p[a] + state.u[3 * i + a]))
        .collect();
    let stress = &source.stress;
    let history = &state.history;
    let eigenstrain = &history.eigenstrain;
    // The displacement is stored exactly (positions = rest + u are rounded), so that a
    // resumed run continues bit for bit.
    let mut node_fields = vec![Field {
        name: "displacement",
        cols: 3,
        data: &state.u,
    }];
    // What the time scheme carries from step to step (Newmark's acceleration, BDF2's step
    // back): what a resumed run continues from. The initial frame has none.
    for (name, data) in &state.carried.fields {
        node_fields.push(Field {
            name,
            cols: 3,
            data,
        });
    }
    let mut attributes = vec![("restart_point", f64::from(u8::from(restart_point)))];
    attributes.extend(state.carried.scalars.iter().copied());
    // With adaptive steps: the length the control proposes for the next step.
    if state.next_dt > 0.0 {
        attributes.push(("next_dt", state.next_dt));
    }
    // With [thermal]: the temperature at every node (°C), read where the heat is solved.
    let temperature = &source.temperature;
    if let Some(t) = &temperature {
        node_fields.push(Field {
            name: "temperature",
            cols: 1,
            data: t,
        });
    }
    let zeros;
    let active: Vec<f64>;
    if let Some(forces) = source.contact {
        let (normal, friction) = if forces.normal.is_empty() {
            zeros = vec![0.0; state.u.len()];
            (&zeros[..], &zeros[..])
        } else {
            (&forces.normal[..], &forces.friction[..])
        };
        node_fields.push(Field {
            name: "contact_normal_force",
            cols: 3,
            data: normal,
        });
        node_fields.push(Field {
            name: "contact_friction_force",
            cols: 3,
            data: friction,
        });
        active = normal
            .chunks(3)
            .map(|f| f64::from(u8::from(f.iter().any(|x| *x != 0.0))))
            .collect();
        node_fields.push(Field {
            name: "contact_active",
            cols: 1,
            data: &active,
        });
    }
    let mut element_fields = vec![Field {
        name: "eigenstrain",
        cols: 1,
        data: eigenstrain,
    }];
    if !history.freeze_state.is_empty() {
        element_fields.push(Field {
            name: "freeze_state",
            cols: 1,
            data: &history.freeze_state,
        });
    }
    // What ParaView users would otherwise compute with a calculator, per element.
    let tensors: Vec<_> = stress.iter().map(|s| fem::from_voigt(s)).collect();
    let von_mises: Vec<f64> = tensors.iter().map(fem::von_mises).collect();
    let principal: Vec<f64> = tensors.iter().map(fem::max_principal).collect();
    element_fields.push(Field {
        name: "von_mises",
        cols: 1,
        data: &von_mises,
    });
    element_fields.push(Field {
        name: "max_principal_stress",
        cols: 1,
        data: &principal,
    });
    let plastic: Vec<f64> = history
        .plastic_strain
        .iter()
        .flat_map(fem::to_voigt)
        .collect();
    let plastic_norm: Vec<f64> = history.plastic_strain.iter().map(|e| e.norm()).collect();
    if !plastic.is_empty() {
        element_fields.push(Field {
            name: "plastic_strain",
            cols: 6,
            data: &plastic,
        });
        element_fields.push(Field {
            name: "plastic_strain_norm",
            cols: 1,
            data: &plastic_norm,
        });
    }
    // Which scene element each element lies in: what a resumed fracture run rebuilds from.
    let origin: Vec<f64> = fracture.map_or(Vec::new(), |(f, _)| {
        f.origin.iter().map(|&o| o as f64).collect()
    });
    if fracture.is_some() {
        element_fields.push(Field {
            name: "origin",
            cols: 1,
            data: &origin,
        });
    }
    // Refused splits (reason code and crack normal per node): what a resumed run must not
    // retry either.
    let refused: Vec<f64> = fracture.map_or(Vec::new(), |(f, _)| {
        f.refusals_as_rows(source.mesh.num_nodes())
    });
    if fracture.is_some() {
        node_fields.push(Field {
            name: "refused_split",
            cols: 4,
            data: &refused,
        });
    }
    let cracks = fracture.map(|(f, sim)| f.surface(sim));
    writer.write_frame(&Frame {
        step: state.step,
        time: state.time,
        positions: &positions,
        velocities: as_rows(&state.v),
        rest_positions: &rest,
        tets: &source.mesh.tets,
        topology_changed,
        stress,
        element_fields: &element_fields,
        node_fields: &node_fields,
        attributes: &attributes,
        cracks: cracks.as_ref(),
    })
}

fn restore(
    sim: &mut Simulation,
    mut fracture: Option<&mut Fracture>,
    path: &Path,
    frame: &crate::output::ResumeFrame,
    scene_text: &str,
) -> Result<(), RunError> {
    let bad = |reason: String| RunError::Resume {
        path: path.into(),
        reason,
    };
    if frame.scene_text != scene_text {
        return Err(bad(
            "it was written from a different scene text (resume needs the same scene)".into(),
        ));
    }
    let rest = rows(&sim.model.mesh.rest);
    if frame.rest_positions != rest || frame.tets != sim.model.mesh.tets {
        // A fractured run: rebuild its mesh from the scene's, element by element.
        let Some(fracture) = fracture.as_deref_mut() else {
            return Err(bad("its mesh differs from the scene's mesh".into()));
        };
        let origin: Vec<usize> = frame
            .element_fields
            .iter()
            .find(|f| f.name == "origin" && f.columns == 1 && f.data.len() == frame.tets.len())
            .filter(|f| {
                let scene_tets = sim.model.mesh.num_tets() as f64;
                f.data
                    .iter()
                    .all(|&o| o >= 0.0 && o < scene_tets && o.fract() == 0.0)
            })
            .map(|f| f.data.iter().map(|&o| o as usize).collect())
            .ok_or_else(|| {
                bad("its mesh was split but the frame has no valid element field `origin`".into())
            })?;
        let frame_rest: Vec<nalgebra::Vector3<f64>> =
            frame.rest_positions.iter().map(|p| (*p).into()).collect();
        let zeros = vec![0.0; 3 * frame_rest.len()];
        let mut split = Fracturable::new(frame_rest, frame.tets.clone(), zeros.clone(), zeros);
        split.parent = origin.clone();
        fracture.rebuild(sim, split, origin)?;
    }
    let rest = rows(&sim.model.mesh.rest);
    let n = 3 * rest.len();
    if let (Some(fracture), Some(f)) = (
        fracture,
        frame.node_fields.iter().find(|f| {
            f.name == "refused_split" && f.columns == 4 && f.data.len() == 4 * rest.len()
        }),
    ) {
        fracture.restore_refusals(&f.data);
    }
    let field = |name: &str| {
        frame
            .node_fields
            .iter()
            .find(|f| f.name == name && f.columns == 3 && f.data.len() == n)
            .map(|f| f.data.clone())
    };
    let u = field("displacement")
        .ok_or_else(|| bad("the last complete frame has no node field `displacement`".into()))?;
    if frame.velocities.len() != rest.len() {
        return Err(bad("the velocities do not match the mesh".into()));
    }
    sim.state.u = u;
    sim.state.v = frame.velocities.iter().flatten().copied().collect();
    // What the time scheme carries (absent in a frame written before the first step or after
    // a split: then the next step starts as the first does).
    sim.state.carried = SchemeState::read(sim.integrator(), field, |name| frame.attribute(name));
    sim.state.next_dt = frame.attribute("next_dt").unwrap_or(0.0);
    sim.state.time = frame.time;
    sim.state.step = frame.step;
    if let Some(scene_nodes) = sim.heat().map(|l| l.heat.temperature().len()) {
        // The scene mesh's nodes keep their numbers through splits: its temperatures are the
        // first entries of the frame's node field.
        let t = frame
            .node_fields
            .iter()
            .find(|f| f.name == "temperature" && f.columns == 1 && f.data.len() >= scene_nodes)
            .ok_or_else(|| bad("the last complete frame has no node field `temperature`".into()))?;
        sim.set_temperature(t.data[..scene_nodes].to_vec());
    }
    let tets = sim.model.mesh.num_tets();
    if let Some(e) = frame
        .element_fields
        .iter()
        .find(|f| f.name == "eigenstrain")
    {
        if e.columns == 1 && e.data.len() == tets {
            sim.state.history.eigenstrain = e.data.clone();
        }
    }
    sim.model.apply_schedule(frame.time, &mut sim.state.history);
    if sim.model.elasticity.plasticity.is_some() {
        let p = frame
            .element_fields
            .iter()
            .find(|f| f.name == "plastic_strain" && f.columns == 6 && f.data.len() == 6 * tets)
            .ok_or_else(|| {
                bad("the last complete frame has no element field `plastic_strain`".into())
            })?;
        sim.state.history.plastic_strain = p.data.chunks(6).map(fem::from_voigt).collect();
    }
    Ok(())
}
