//! `icefem` command line: parses arguments, runs the library, reports.

use anyhow::{Context, Result};
use clap::{Parser, Subcommand};
use icefem::run::{run, Progress, RunOptions};
use icefem::scene::Scene;
use indicatif::{ProgressBar, ProgressStyle};
use std::io::IsTerminal;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Instant;

#[derive(Parser)]
#[command(name = "icefem", version, about = "Implicit FEM simulator of ice cracking as it freezes")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Simulate a scene and write every output frame to HDF5 (plus an XDMF sidecar).
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
    },
    /// Print what an icefem HDF5 file holds.
    Info {
        /// HDF5 file written by `icefem run`.
        file: PathBuf,
    },
}

fn main() {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Run { scene, output, end_time, dt, resume } => {
            let options = RunOptions { output: resume.clone().or(output), end_time, dt, resume: resume.is_some() };
            run_command(&scene, &options)
        }
        Command::Info { file } => icefem::output::describe(&file).map(|text| print!("{text}")).map_err(Into::into),
    };
    if let Err(e) = result {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}

fn run_command(scene_path: &PathBuf, options: &RunOptions) -> Result<()> {
    let scene = Scene::load(scene_path)?;
    let interrupt = Arc::new(AtomicBool::new(false));
    {
        let flag = interrupt.clone();
        // A second Ctrl-C while the first is being honoured kills the process the usual way.
        ctrlc::set_handler(move || {
            if flag.swap(true, Ordering::SeqCst) {
                std::process::exit(130);
            }
        })
        .context("installing the Ctrl-C handler")?;
    }
    let m = &scene.model;
    eprintln!(
        "icefem {}: {} — {} nodes, {} tets, {:?} {:?}, dt = {:e} s",
        env!("CARGO_PKG_VERSION"),
        scene_path.display(),
        m.num_nodes(),
        m.mesh.num_tets(),
        scene.settings.analysis,
        m.elasticity.model,
        options.dt.unwrap_or(scene.settings.dt),
    );
    let terminal = std::io::stderr().is_terminal();
    let bar = ProgressBar::hidden();
    if terminal {
        bar.set_draw_target(indicatif::ProgressDrawTarget::stderr());
        bar.set_style(
            ProgressStyle::with_template("{bar:40} {pos}/{len} steps  t = {msg}  [{elapsed_precise} < {eta}]")
                .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
    }
    let start = Instant::now();
    let mut last_log = Instant::now();
    let summary = run(&scene, options, &interrupt, |p: &Progress| {
        if terminal {
            bar.set_length(p.total_steps);
            bar.set_position(p.step);
            bar.set_message(format!("{:.4} s", p.time));
        } else if p.step == p.total_steps || last_log.elapsed().as_secs_f64() >= 2.0 || p.step <= 1 {
            last_log = Instant::now();
            eprintln!(
                "step {}/{}  t = {:.4} s  newton {}  residual {:.2e} N  energy {:.4e} J  {:.3} s/step",
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
    if summary.interrupted {
        eprintln!("resume with: icefem run {} --resume {}", scene_path.display(), summary.output.display());
        std::process::exit(130);
    }
    Ok(())
}
