//! The `icefem bench` subcommand: runs the benchmark problems at each size, repeats them,
//! takes medians and formats the markdown tables, which it hands over line by line.
//!
//! The solver benchmark runs every repeat in a fresh process of this executable
//! (`icefem bench --single N …`, see [`BenchCommand::Single`]), so that the peak memory it
//! reports is that of one run; that process prints one line of [`SINGLE_FIELDS`] numbers.

use super::problems::{contact_cost, fracture_cost, run_size, BenchResult, FractureCost};
use super::{median_of, BenchError};
use crate::solver::{FillOrdering, LinearSolverKind};
use std::path::Path;

/// How one run of the solver benchmark steps the ice cube.
#[derive(Clone, Copy, Debug)]
pub struct SolverOptions {
    /// Backward-Euler steps per run (at least one is taken); per-step figures are medians over
    /// them.
    pub steps: usize,
    /// Linear solver.
    pub linear: LinearSolverKind,
    /// Cholesky fill-reducing ordering.
    pub ordering: FillOrdering,
    /// Multigrid keeps its hierarchy across Hessian refreshes.
    pub amg_reuse: bool,
}

/// One `icefem bench` invocation.
#[derive(Clone, Debug)]
pub enum BenchCommand {
    /// The solver benchmark: a table of medians over `repeats` runs (at least one, each in a
    /// fresh process) per approximate tet count in `tets`, then the scaling exponents when
    /// there are two sizes or more.
    Solver {
        /// Approximate tet counts.
        tets: Vec<usize>,
        /// Runs per size.
        repeats: usize,
        /// How each run steps.
        options: SolverOptions,
    },
    /// One run of the solver benchmark in this process, printed as one line of
    /// [`SINGLE_FIELDS`] numbers.
    Single {
        /// Approximate tet count.
        tets: usize,
        /// How the run steps.
        options: SolverOptions,
    },
    /// The per-step cost of contact against the elastic assembly, per size with the container
    /// as planes and as a triangle mesh: medians over `repeats` runs of `steps` steps each.
    Contact {
        /// Approximate tet counts (both cubes together).
        tets: Vec<usize>,
        /// Steps per run (at least one).
        steps: usize,
        /// Runs per size (at least one).
        repeats: usize,
    },
    /// The cost of the fracture check and of one split per size: medians over `repeats` runs.
    Fracture {
        /// Approximate tet counts.
        tets: Vec<usize>,
        /// Runs per size (at least one).
        repeats: usize,
    },
}

/// Names of the numbers [`BenchCommand::Single`] prints, in order (times in s, peak memory in
/// bytes, 0 where the OS does not report it); `validation/bench.py` reads them by these names.
pub const SINGLE_FIELDS: [&str; 20] = [
    "tets",
    "dofs",
    "nnz",
    "nnz_L",
    "t_model",
    "t_pattern",
    "t_symbolic",
    "t_assembly_step",
    "t_factor_step",
    "t_solve_step",
    "t_step",
    "newton",
    "lin_it",
    "peak_rss",
    "t_first_setup",
    "t_first_solve",
    "first_it",
    "amg_levels",
    "amg_complexity",
    "setups",
];

impl BenchResult {
    /// The result as the [`SINGLE_FIELDS`] numbers.
    pub fn fields(&self) -> [f64; SINGLE_FIELDS.len()] {
        [
            self.tets as f64,
            self.dofs as f64,
            self.nnz as f64,
            self.factor_nnz as f64,
            self.t_model,
            self.t_pattern,
            self.t_symbolic,
            self.t_assembly,
            self.t_factorization,
            self.t_solve,
            self.t_step,
            self.newton_iterations as f64,
            self.linear_iterations as f64,
            self.peak_memory.unwrap_or(0) as f64,
            self.t_first_setup,
            self.t_first_solve,
            self.first_iterations as f64,
            self.levels as f64,
            self.operator_complexity,
            self.setups as f64,
        ]
    }

    /// The result from its [`SINGLE_FIELDS`] numbers (the inverse of [`BenchResult::fields`];
    /// a peak memory of 0 reads as `Some(0)`).
    pub fn from_fields(v: [f64; SINGLE_FIELDS.len()]) -> Self {
        BenchResult {
            tets: v[0] as usize,
            dofs: v[1] as usize,
            nnz: v[2] as usize,
            factor_nnz: v[3] as usize,
            t_model: v[4],
            t_pattern: v[5],
            t_symbolic: v[6],
            t_assembly: v[7],
            t_factorization: v[8],
            t_solve: v[9],
            t_step: v[10],
            newton_iterations: v[11] as usize,
            linear_iterations: v[12] as usize,
            peak_memory: Some(v[13] as u64),
            t_first_setup: v[14],
            t_first_solve: v[15],
            first_iterations: v[16] as usize,
            levels: v[17] as usize,
            operator_complexity: v[18],
            setups: v[19] as usize,
        }
    }

    /// The [`SINGLE_FIELDS`] numbers on one line, separated by spaces, each printed exactly
    /// (shortest form that reads back as the same `f64`).
    pub fn single_line(&self) -> String {
        self.fields().map(|v| v.to_string()).join(" ")
    }

    /// Reads what [`BenchResult::single_line`] printed: the numbers among the
    /// whitespace-separated words of `text`, which must be exactly [`SINGLE_FIELDS`] many.
    pub fn parse_single_line(text: &str) -> Result<Self, BenchError> {
        let values: Vec<f64> = text
            .split_whitespace()
            .filter_map(|v| v.parse().ok())
            .collect();
        let values = values
            .try_into()
            .map_err(|_| BenchError::Malformed(text.to_string()))?;
        Ok(Self::from_fields(values))
    }
}

/// The name `icefem bench --solver` takes for `linear`.
pub fn solver_name(linear: LinearSolverKind) -> &'static str {
    match linear {
        LinearSolverKind::Cholesky => "cholesky",
        LinearSolverKind::Cg => "cg",
        LinearSolverKind::Amg => "amg",
        LinearSolverKind::Auto => "auto",
        LinearSolverKind::Petsc => "petsc",
    }
}

/// The name `icefem bench --ordering` takes for `ordering`.
pub fn ordering_name(ordering: FillOrdering) -> &'static str {
    match ordering {
        FillOrdering::Auto => "auto",
        FillOrdering::Amd => "amd",
        FillOrdering::Metis => "metis",
    }
}

/// Runs `command` and hands its output to `emit`, one line at a time (without the final line
/// break; a line of the tables' preamble may end in `\n`, for a blank line after it). Each
/// table row is handed over as soon as its size has been measured.
///
/// [`BenchCommand::Solver`] starts its runs as processes of the running executable
/// ([`std::env::current_exe`]), which must therefore be `icefem`.
pub fn run(command: &BenchCommand, mut emit: impl FnMut(&str)) -> Result<(), BenchError> {
    let emit: &mut dyn FnMut(&str) = &mut emit;
    match command {
        BenchCommand::Solver {
            tets,
            repeats,
            options,
        } => {
            let exe = std::env::current_exe().map_err(BenchError::Executable)?;
            solver_table(&exe, tets, *repeats, options, emit)
        }
        BenchCommand::Single { tets, options } => {
            let r = run_size(
                *tets,
                options.steps.max(1),
                options.linear,
                options.ordering,
                options.amg_reuse,
            )?;
            emit(&r.single_line());
            Ok(())
        }
        BenchCommand::Contact {
            tets,
            steps,
            repeats,
        } => contact_table(tets, *steps, *repeats, emit),
        BenchCommand::Fracture { tets, repeats } => fracture_table(tets, *repeats, emit),
    }
}

/// `measure` run `repeats` times (at least once), stopping at the first error.
fn repeated<T>(
    repeats: usize,
    mut measure: impl FnMut() -> Result<T, BenchError>,
) -> Result<Vec<T>, BenchError> {
    (0..repeats.max(1)).map(|_| measure()).collect()
}

/// One run of the solver benchmark at ≈ `tets` tets in a fresh process of `exe`.
fn single_process(
    exe: &Path,
    tets: usize,
    options: &SolverOptions,
) -> Result<BenchResult, BenchError> {
    let out = std::process::Command::new(exe)
        .args([
            "bench",
            "--single",
            &tets.to_string(),
            "--steps",
            &options.steps.to_string(),
            "--solver",
            solver_name(options.linear),
            "--ordering",
            ordering_name(options.ordering),
        ])
        .args((!options.amg_reuse).then_some("--no-amg-reuse"))
        .output()
        .map_err(BenchError::Spawn)?;
    if !out.status.success() {
        return Err(BenchError::Failed {
            tets,
            stderr: String::from_utf8_lossy(&out.stderr).into_owned(),
        });
    }
    BenchResult::parse_single_line(&String::from_utf8_lossy(&out.stdout))
}

/// [`BenchCommand::Solver`] with the runs as processes of `exe`.
fn solver_table(
    exe: &Path,
    sizes: &[usize],
    repeats: usize,
    options: &SolverOptions,
    emit: &mut dyn FnMut(&str),
) -> Result<(), BenchError> {
    preamble(
        emit,
        &format!(
            "icefem bench: corotated ice cube (10 cm, base clamped, gravity), backward Euler dt = 1/30 s, {}{}, ordering {}",
            solver_name(options.linear),
            if options.amg_reuse { "" } else { " (no hierarchy reuse)" },
            ordering_name(options.ordering)
        ),
        &format!(
            "medians of {repeats} runs (fresh process each) of the per-step medians over {} steps",
            options.steps
        ),
        "| tets | free dofs | nnz(K) | nnz(L) | pattern (s) | symbolic (s) | assembly/step (s) | factor/step (s) | solve/step (s) | step (s) | Newton it. | lin. it. | peak memory (MB) | first system: setup + solve (s) (it.) | AMG levels / op. complexity | set-ups per run |",
    );
    // (free dofs, step time, first-system time) per size, for the scaling exponents.
    let mut scaling: Vec<(f64, f64, f64)> = Vec::new();
    for &tets in sizes {
        let runs = repeated(repeats, || single_process(exe, tets, options))?;
        emit(&solver_row(&runs));
        let m = |f: fn(&BenchResult) -> f64| median_of(&runs, f);
        scaling.push((
            m(|r| r.dofs as f64),
            m(|r| r.t_step),
            m(|r| r.t_first_setup) + m(|r| r.t_first_solve),
        ));
    }
    if scaling.len() >= 2 {
        emit(&format!(
            "\nScaling exponent (least-squares slope of log time against log free dofs): step {:.2}, first system (set-up + solve) {:.2}",
            loglog_slope(&scaling.iter().map(|p| (p.0, p.1)).collect::<Vec<_>>()),
            loglog_slope(&scaling.iter().map(|p| (p.0, p.2)).collect::<Vec<_>>()),
        ));
    }
    Ok(())
}

/// The solver table's row of one size: field by field, the median over `runs`.
fn solver_row(runs: &[BenchResult]) -> String {
    let m = |f: fn(&BenchResult) -> f64| median_of(runs, f);
    let (setup, solve) = (m(|r| r.t_first_setup), m(|r| r.t_first_solve));
    format!(
        "| {} | {} | {:.2e} | {:.2e} | {:.3} | {:.3} | {:.4} | {:.4} | {:.4} | {:.4} | {} | {} | {:.0} | {:.3} + {:.3} = {:.3} ({}) | {} / {:.2} | {} |",
        m(|r| r.tets as f64),
        m(|r| r.dofs as f64),
        m(|r| r.nnz as f64),
        m(|r| r.factor_nnz as f64),
        m(|r| r.t_pattern),
        m(|r| r.t_symbolic),
        m(|r| r.t_assembly),
        m(|r| r.t_factorization),
        m(|r| r.t_solve),
        m(|r| r.t_step),
        m(|r| r.newton_iterations as f64),
        m(|r| r.linear_iterations as f64),
        m(|r| r.peak_memory.unwrap_or(0) as f64) / 1e6,
        setup,
        solve,
        setup + solve,
        m(|r| r.first_iterations as f64),
        m(|r| r.levels as f64),
        m(|r| r.operator_complexity),
        m(|r| r.setups as f64),
    )
}

/// [`BenchCommand::Contact`].
fn contact_table(
    sizes: &[usize],
    steps: usize,
    repeats: usize,
    emit: &mut dyn FnMut(&str),
) -> Result<(), BenchError> {
    preamble(
        emit,
        "icefem bench --contact: two corotated ice cubes stacked (offset) in a container, friction 0.3, gravity, backward Euler dt = 1/30 s, Cholesky",
        &format!("medians of {repeats} runs of the per-step medians over {steps} steps"),
        "| tets | container | boundary nodes | ice–ice pairs | Newton it./step | broad phase/step (ms) | narrow phase/step (ms) | elastic assembly/step (ms) | contact / elastic | step (ms) |",
    );
    for &tets in sizes {
        for mesh_container in [false, true] {
            let runs = repeated(repeats, || {
                Ok(contact_cost(tets, steps.max(1), mesh_container)?)
            })?;
            let (broad, narrow, elastic) = (
                median_of(&runs, |c| c.t_broad),
                median_of(&runs, |c| c.t_narrow),
                median_of(&runs, |c| c.t_elastic),
            );
            let r = &runs[0];
            emit(&format!(
                "| {} | {} | {} | {} | {} | {:.2} | {:.2} | {:.2} | {:.3} | {:.1} |",
                r.tets,
                if mesh_container {
                    "triangle mesh"
                } else {
                    "planes"
                },
                r.boundary_nodes,
                r.candidates,
                r.newton_iterations,
                1e3 * broad,
                1e3 * narrow,
                1e3 * elastic,
                (broad + narrow) / elastic,
                1e3 * median_of(&runs, |c| c.t_step),
            ));
        }
    }
    Ok(())
}

/// [`BenchCommand::Fracture`].
fn fracture_table(
    sizes: &[usize],
    repeats: usize,
    emit: &mut dyn FnMut(&str),
) -> Result<(), BenchError> {
    preamble(
        emit,
        "icefem bench --fracture: a corotated 10 cm ice cube pulled to σ ≈ 1e7 Pa in one step of 1/30 s (τ = 3e6 Pa), then one split; Cholesky",
        &format!("medians of {repeats} runs"),
        "| tets | step (ms) | fracture check (ms) | split (ms) | remesh (ms) | step re-solved (ms) |",
    );
    for &tets in sizes {
        let runs = repeated(repeats, || Ok(fracture_cost(tets)?))?;
        let ms = |f: fn(&FractureCost) -> f64| 1e3 * median_of(&runs, f);
        emit(&format!(
            "| {} | {:.1} | {:.2} | {:.2} | {:.1} | {:.1} |",
            runs[0].tets,
            ms(|c| c.t_step),
            ms(|c| c.t_check),
            ms(|c| c.t_split),
            ms(|c| c.t_remesh),
            ms(|c| c.t_resolve),
        ));
    }
    Ok(())
}

/// A table's preamble: `title`; the number of threads, then `medians` (what the figures are
/// medians of) and a blank line; the markdown `header` row and the rule under it.
fn preamble(emit: &mut dyn FnMut(&str), title: &str, medians: &str, header: &str) {
    emit(title);
    emit(&format!(
        "{} threads; {medians}\n",
        rayon::current_num_threads()
    ));
    emit(header);
    emit(&table_rule(header.matches('|').count() - 1));
}

/// The markdown line under a header of `columns` columns: `|---|---|…|`.
fn table_rule(columns: usize) -> String {
    format!("|{}", "---|".repeat(columns))
}

/// Least-squares slope of log y against log x over the points (x, y): the exponent p of
/// y ∝ xᵖ. NaN for fewer than two distinct x.
pub fn loglog_slope(points: &[(f64, f64)]) -> f64 {
    let logs: Vec<(f64, f64)> = points.iter().map(|&(x, y)| (x.ln(), y.ln())).collect();
    let n = logs.len() as f64;
    let mx = logs.iter().map(|p| p.0).sum::<f64>() / n;
    let my = logs.iter().map(|p| p.1).sum::<f64>() / n;
    let sxy: f64 = logs.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    let sxx: f64 = logs.iter().map(|p| (p.0 - mx).powi(2)).sum();
    sxy / sxx
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One line as `icefem bench --single 100 --steps 1` prints it.
    const LINE: &str = "162 144 3978 3762 0.000162828 0.004946807 0.000287263 0.0004998209999999999 0.000214638 0.000050184 0.000870563 2 2 13238272 0.000501901 0.000025092 1 0 0 1\n";

    #[test]
    fn single_line_reads_back_exactly() {
        let r = BenchResult::parse_single_line(LINE).expect("20 numbers");
        assert_eq!(r.tets, 162);
        assert_eq!(r.peak_memory, Some(13_238_272));
        assert_eq!(r.t_symbolic, 0.000287263);
        assert_eq!(r.t_assembly, 0.0004998209999999999);
        assert_eq!(format!("{}\n", r.single_line()), LINE);
        assert_eq!(BenchResult::from_fields(r.fields()).fields(), r.fields());
    }

    #[test]
    fn single_line_of_other_length_is_malformed() {
        let short = "162 144 3978";
        match BenchResult::parse_single_line(short) {
            Err(e @ BenchError::Malformed(_)) => {
                assert_eq!(e.to_string(), "malformed benchmark output: 162 144 3978")
            }
            other => panic!("expected Malformed, got {other:?}"),
        }
        assert!(BenchResult::parse_single_line(&format!("{LINE} 7")).is_err());
        let failed = BenchError::Failed {
            tets: 1000,
            stderr: "error: x\n".into(),
        };
        assert_eq!(
            failed.to_string(),
            "benchmark at 1000 tets failed: error: x\n"
        );
    }

    #[test]
    fn solver_row_formats_medians() {
        let r = BenchResult::parse_single_line(LINE).expect("20 numbers");
        let slower = BenchResult {
            t_step: 0.5,
            ..r.clone()
        };
        assert_eq!(
            solver_row(&[r.clone(), slower.clone(), slower]),
            "| 162 | 144 | 3.98e3 | 3.76e3 | 0.005 | 0.000 | 0.0005 | 0.0002 | 0.0001 | 0.5000 | 2 | 2 | 13 | 0.001 + 0.000 = 0.001 (1) | 0 / 0.00 | 1 |"
        );
        assert_eq!(table_rule(3), "|---|---|---|");
    }

    #[test]
    fn loglog_slope_of_a_power_law() {
        let p: Vec<(f64, f64)> = [1e3f64, 1e4, 1e5]
            .iter()
            .map(|&x| (x, 2.0 * x * x.sqrt()))
            .collect();
        assert!((loglog_slope(&p) - 1.5).abs() < 1e-12);
        assert!(loglog_slope(&p[..1]).is_nan());
    }

    /// `validation/bench.py` names the numbers of `icefem bench --single` in the same order.
    #[test]
    fn bench_py_reads_the_single_fields() {
        let script = include_str!("../../validation/bench.py");
        let start = script
            .find("ICEFEM_FIELDS = [")
            .expect("bench.py defines ICEFEM_FIELDS");
        let list = &script[start..];
        let list = &list[..list.find(']').expect("a closing bracket")];
        let names: Vec<&str> = list.split('"').skip(1).step_by(2).collect();
        assert_eq!(names, SINGLE_FIELDS);
    }
}
