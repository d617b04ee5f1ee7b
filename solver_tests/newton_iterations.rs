//! A regression guard on Newton's cost: shipped scenes run to their end, and their Newton
//! iterations per step (`/stats/newton_iterations`) must stay near what was measured.
//!
//! The bounds are the measured median and largest count times 1.5 (the median plus one, for
//! medians of 0–1): the counts are deterministic for a build, but change with the order of
//! floating-point sums (another compiler, another thread count), which moves a count by an
//! iteration or two; a change to the solver that doubles them fails. The measurements:
//! `validation/newton_iterations.py target/release/icefem` (2-core machine).

use icefem::run::{run, RunOptions};
use icefem::scene::Scene;
use std::path::Path;
use std::sync::atomic::AtomicBool;

/// A scene (relative to the repository) and its measured median and largest Newton
/// iterations per step.
struct Measured {
    scene: &'static str,
    median: f64,
    largest: u32,
}

const MEASURED: &[Measured] = &[
    Measured {
        scene: "scenes/gallery/thrown_cube_paddle.toml",
        median: 4.0,
        largest: 74,
    },
    Measured {
        scene: "scenes/gallery/water_sphere_in_cup.toml",
        median: 3.0,
        largest: 127,
    },
    Measured {
        scene: "scenes/gallery/water_sphere_thermal.toml",
        median: 6.0,
        largest: 15,
    },
    Measured {
        scene: "scenes/gallery/two_material_block.toml",
        median: 0.0,
        largest: 5,
    },
    Measured {
        scene: "scenes/gallery/beam_bent.toml",
        median: 4.0,
        largest: 4,
    },
    Measured {
        scene: "scenes/freezing_container_fracture.toml",
        median: 3.0,
        largest: 48,
    },
    Measured {
        scene: "scenes/freezing_container.toml",
        median: 3.0,
        largest: 25,
    },
    Measured {
        scene: "scenes/drop_into_container.toml",
        median: 1.0,
        largest: 20,
    },
    Measured {
        scene: "scenes/slide_down_ramp.toml",
        median: 0.0,
        largest: 173,
    },
    Measured {
        scene: "scenes/stacked_cubes.toml",
        median: 9.5,
        largest: 37,
    },
    // Users' fracture scenes on Gmsh meshes: besides the counts, they must run to their end.
    Measured {
        scene: "scenes/gallery/glass_column.toml",
        median: 4.0,
        largest: 45,
    },
    Measured {
        scene: "scenes/gallery/ball_cracking_in_cup.toml",
        median: 3.0,
        largest: 291,
    },
    Measured {
        scene: "scenes/gallery/bottle_thermal.toml",
        median: 6.0,
        // Measured 24 (validation/newton_iterations.md). The bound keeps 42: with other
        // restart points (a fresh factorisation every 5 steps) three steps met an indefinite
        // Hessian and finished on its projection (`/stats/projections`) in 27, 29 and 42 —
        // how far this count moves with the iterates' history.
        largest: 42,
    },
];

/// Median of `v` (sorted in place).
fn median(v: &mut [u32]) -> f64 {
    v.sort_unstable();
    let n = v.len();
    if n % 2 == 1 {
        f64::from(v[n / 2])
    } else {
        0.5 * f64::from(v[n / 2 - 1] + v[n / 2])
    }
}

#[test]
fn newton_iterations_per_step_stay_near_their_measured_counts() {
    let repo = Path::new(env!("CARGO_MANIFEST_DIR"));
    let dir = tempfile::tempdir().unwrap();
    let mut failures = Vec::new();
    for m in MEASURED {
        let path = repo.join(m.scene);
        let scene = Scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
        let output = dir
            .path()
            .join(path.file_name().unwrap())
            .with_extension("h5");
        let options = RunOptions {
            output: Some(output.clone()),
            ..Default::default()
        };
        run(&scene, &options, &AtomicBool::new(false), |_| {})
            .unwrap_or_else(|e| panic!("{}: {e}", m.scene));
        let file = hdf5::File::open(&output).unwrap();
        let mut counts: Vec<u32> = file
            .dataset("stats/newton_iterations")
            .unwrap()
            .read_raw::<u32>()
            .unwrap();
        let largest = *counts.iter().max().unwrap();
        let med = median(&mut counts);
        let median_bound = if m.median <= 1.0 {
            m.median + 1.0
        } else {
            1.5 * m.median
        };
        let largest_bound = (1.5 * f64::from(m.largest)).ceil() as u32;
        eprintln!(
            "{}: median {med} (bound {median_bound}), largest {largest} (bound {largest_bound})",
            m.scene
        );
        if med > median_bound || largest > largest_bound {
            failures.push(format!(
                "{}: median {med} > {median_bound} or largest {largest} > {largest_bound}",
                m.scene
            ));
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}
