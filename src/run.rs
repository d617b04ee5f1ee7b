//! A whole run: scene → simulation → HDF5 frames, with resume and clean interruption.

use crate::output::{Field, Frame, OutputError, OutputWriter, RunHeader, StepStats};
use crate::scene::{Scene, SceneError};
use crate::sim::{SimError, Simulation, StepReport};
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
    /// The step's report.
    pub report: &'a StepReport,
}

/// Number of steps to reach `end_time` with steps of `dt` (a last partial step is not taken;
/// a hair's round-off below a whole number counts as whole).
pub fn step_count(end_time: f64, dt: f64) -> u64 {
    (end_time / dt + 1e-9).floor() as u64
}

/// Runs `scene` with `options`, calling `progress` after every step; stops early (cleanly, with
/// the last state written) once `interrupt` is set.
pub fn run(
    scene: &Scene,
    options: &RunOptions,
    interrupt: &AtomicBool,
    mut progress: impl FnMut(&Progress),
) -> Result<RunSummary, RunError> {
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
    let mut sim = Simulation::new(scene.model.clone(), settings)?;
    let rest: Vec<[f64; 3]> = sim
        .model
        .mesh
        .rest
        .iter()
        .map(|p| [p.x, p.y, p.z])
        .collect();
    let mut writer = if options.resume {
        let (writer, frame) = OutputWriter::resume(&output)?;
        restore(&mut sim, &output, &frame, &rest, &scene.text)?;
        writer
    } else {
        let header = RunHeader {
            scene_text: &scene.text,
            scene_path: &scene.path.to_string_lossy(),
            version: env!("CARGO_PKG_VERSION"),
            rest_positions: &rest,
            tets: &sim.model.mesh.tets,
        };
        let mut writer = OutputWriter::create(&output, &header)?;
        write_frame(&mut writer, &sim, &rest, true)?;
        writer
    };
    let total_steps = step_count(end_time, settings.dt);
    let mut summary = RunSummary {
        output: output.clone(),
        ..Default::default()
    };
    while sim.state.step < total_steps {
        if interrupt.load(Ordering::SeqCst) {
            summary.interrupted = true;
            break;
        }
        let report = sim.step()?;
        summary.steps += 1;
        summary.newton_iterations += report.newton.iterations as u64;
        summary.max_residual = summary.max_residual.max(report.newton.residual);
        writer.append_stats(&stats_row(&sim, &report))?;
        let last = sim.state.step == total_steps;
        if sim.state.step % scene.output_every == 0 || last || interrupt.load(Ordering::SeqCst) {
            write_frame(&mut writer, &sim, &rest, false)?;
        }
        progress(&Progress {
            step: sim.state.step,
            total_steps,
            time: sim.state.time,
            report: &report,
        });
    }
    summary.final_step = sim.state.step;
    summary.final_time = sim.state.time;
    summary.frames = writer.frame_count();
    writer.finish()?;
    Ok(summary)
}

fn stats_row(sim: &Simulation, report: &StepReport) -> StepStats {
    let n = &report.newton;
    StepStats {
        step: sim.state.step,
        time: sim.state.time,
        dt: sim.settings.dt,
        newton_iterations: n.iterations as u32,
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
    }
}

fn as_rows(v: &[f64]) -> &[[f64; 3]] {
    // Plain reinterpretation of a flat 3n vector as n rows; lengths are multiples of 3 by
    // construction.
    let (rows, rest) = v.as_chunks::<3>();
    debug_assert!(rest.is_empty());
    rows
}

fn write_frame(
    writer: &mut OutputWriter,
    sim: &Simulation,
    rest: &[[f64; 3]],
    first: bool,
) -> Result<(), OutputError> {
    let positions = sim.positions();
    let stress = sim.stresses();
    let eigenstrain = &sim.model.elasticity.eigenstrain;
    // The displacement is stored exactly (positions = rest + u are rounded), so that a
    // resumed run continues bit for bit.
    let mut node_fields = vec![Field {
        name: "displacement",
        cols: 3,
        data: &sim.state.u,
    }];
    let zeros;
    let active: Vec<f64>;
    if let Some(forces) = sim.contact_forces() {
        let (normal, friction) = if forces.normal.is_empty() {
            zeros = vec![0.0; sim.state.u.len()];
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
    let el = &sim.model.elasticity;
    let mut element_fields = vec![Field {
        name: "eigenstrain",
        cols: 1,
        data: eigenstrain,
    }];
    if !el.freeze_state.is_empty() {
        element_fields.push(Field {
            name: "freeze_state",
            cols: 1,
            data: &el.freeze_state,
        });
    }
    let plastic: Vec<f64> = el
        .plastic_strain
        .iter()
        .flat_map(crate::fem::to_voigt)
        .collect();
    if !plastic.is_empty() {
        element_fields.push(Field {
            name: "plastic_strain",
            cols: 6,
            data: &plastic,
        });
    }
    writer.write_frame(&Frame {
        step: sim.state.step,
        time: sim.state.time,
        positions: &positions,
        velocities: as_rows(&sim.state.v),
        rest_positions: rest,
        tets: &sim.model.mesh.tets,
        topology_changed: first,
        stress: &stress,
        element_fields: &element_fields,
        node_fields: &node_fields,
    })
}

/// Symmetric tensor from Voigt order xx yy zz yz xz xy (the inverse of `fem::to_voigt`).
fn from_voigt(v: &[f64]) -> nalgebra::Matrix3<f64> {
    nalgebra::Matrix3::new(v[0], v[5], v[4], v[5], v[1], v[3], v[4], v[3], v[2])
}

fn restore(
    sim: &mut Simulation,
    path: &Path,
    frame: &crate::output::ResumeFrame,
    rest: &[[f64; 3]],
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
    if frame.rest_positions.as_slice() != rest || frame.tets != sim.model.mesh.tets {
        return Err(bad("its mesh differs from the scene's mesh".into()));
    }
    let n = 3 * rest.len();
    let field = |name: &str| {
        frame
            .node_fields
            .iter()
            .find(|f| f.0 == name && f.1 == 3 && f.2.len() == n)
            .map(|f| f.2.clone())
    };
    let u = field("displacement")
        .ok_or_else(|| bad("the last complete frame has no node field `displacement`".into()))?;
    if frame.velocities.len() != rest.len() {
        return Err(bad("the velocities do not match the mesh".into()));
    }
    sim.state.u = u;
    sim.state.v = frame.velocities.iter().flatten().copied().collect();
    sim.state.time = frame.time;
    sim.state.step = frame.step;
    let tets = sim.model.mesh.num_tets();
    if let Some((_, 1, e)) = frame.element_fields.iter().find(|f| f.0 == "eigenstrain") {
        if e.len() == tets {
            sim.model.elasticity.eigenstrain = e.clone();
        }
    }
    sim.model.apply_schedule(frame.time);
    if sim.model.plasticity.is_some() {
        let p = frame
            .element_fields
            .iter()
            .find(|f| f.0 == "plastic_strain" && f.1 == 6 && f.2.len() == 6 * tets)
            .ok_or_else(|| {
                bad("the last complete frame has no element field `plastic_strain`".into())
            })?;
        sim.model.elasticity.plastic_strain = p.2.chunks(6).map(from_voigt).collect();
    }
    Ok(())
}
