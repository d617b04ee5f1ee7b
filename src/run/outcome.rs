//! What a run did physically, told after it in a few lines: cracks or none (the largest
//! separation stress against the toughness), the frozen fraction, the largest inelastic strain,
//! and a body that fell far out of every obstacle's reach (most likely a mesh in other units).

use crate::physics::contact::{Obstacle, Shape};
use crate::sim::Simulation;
use nalgebra::Vector3;

/// Fracture over a run.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FractureOutcome {
    /// Node splits made in this invocation.
    pub events: u64,
    /// Crack area at the end (m², one side of each crack face).
    pub crack_area: f64,
    /// Largest separation stress of any step (Pa).
    pub largest_stress: f64,
    /// The toughness τ (Pa).
    pub toughness: f64,
    /// The stress plastic flow caps the deviatoric stress of ice at, 2 μ γ (Pa), with
    /// `[plasticity]`.
    pub yield_stress: Option<f64>,
}

/// What a run did physically (see the module's doc).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Outcome {
    /// Fracture, with `[fracture]`.
    pub fracture: Option<FractureOutcome>,
    /// Frozen share of the volume at the end (freeze state by rest volume), with freezing.
    pub frozen_fraction: Option<f64>,
    /// Largest Frobenius norm of an element's inelastic strain at the end (plastic, crept or
    /// formed; the output's `plastic_strain_norm`), where the scene has one.
    pub largest_inelastic_strain: Option<f64>,
    /// What looks like a mistake (one line each).
    pub warnings: Vec<String>,
}

/// How many times its own size a body may fall out of every obstacle's reach before its units
/// are in doubt (a 7 cm glass of water written in millimetres falls 4.4 km in 30 s).
const FALL_LIMIT: f64 = 10.0;

impl FractureOutcome {
    /// Folds one step's largest separation stress (Pa) and splits in.
    pub fn add_step(&mut self, largest_stress: f64, events: usize) {
        self.largest_stress = self.largest_stress.max(largest_stress);
        self.events += events as u64;
    }
}

impl Outcome {
    /// The state at the end of a run of `sim` as an outcome, with the fracture already
    /// folded in; in a distributed run from sums and maxima over the processes' own elements
    /// and owned nodes (every process calls it).
    pub fn at_end(sim: &Simulation, fracture: Option<FractureOutcome>) -> Self {
        let model = &sim.model;
        let history = &sim.state.history;
        let mesh = &model.mesh;
        let own = || (0..mesh.num_tets()).filter(|&e| sim.evaluates(e));
        let frozen_fraction = (!history.freeze_state.is_empty()).then(|| {
            let volume: f64 = own().map(|e| mesh.signed_volume(e)).sum();
            let frozen: f64 = own()
                .map(|e| mesh.signed_volume(e) * history.freeze_state[e])
                .sum();
            sim.sum_over_processes(frozen) / sim.sum_over_processes(volume)
        });
        let largest_inelastic_strain = (!history.plastic_strain.is_empty()).then(|| {
            let largest = own()
                .map(|e| history.plastic_strain[e].norm())
                .fold(0.0, f64::max);
            sim.max_over_processes(largest)
        });
        let mut warnings = Vec::new();
        if let Some(fall) = fall_out_of_reach(sim) {
            warnings.push(format!(
                "the ice fell {:.3e} m, {:.0} times its own size, and is out of every obstacle's reach: if the mesh file is in millimetres, set its scale to 0.001 ([mesh] scale, or scale in its [[body]])",
                fall.0, fall.1
            ));
        }
        Outcome {
            fracture,
            frozen_fraction,
            largest_inelastic_strain,
            warnings,
        }
    }
}

/// How far (m) and how many of its own sizes the ice's centre of mass fell along gravity,
/// when that is more than [`FALL_LIMIT`] sizes and no node is within one size of an obstacle
/// (`None` otherwise, or when the scene has no obstacle or no gravity).
fn fall_out_of_reach(sim: &Simulation) -> Option<(f64, f64)> {
    let model = &sim.model;
    let obstacles = &model.obstacle_contact()?.obstacles;
    let down = model.gravity.try_normalize(0.0)?;
    let mesh = &model.mesh;
    let (lo, hi) = mesh.bounding_box();
    let (lo, hi) = (
        lo.map(|x| -sim.max_over_processes(-x)),
        hi.map(|x| sim.max_over_processes(x)),
    );
    let size = (hi - lo).norm();
    let u = &sim.state.u;
    let displacement = |i: usize| Vector3::new(u[3 * i], u[3 * i + 1], u[3 * i + 2]);
    let owned = || (0..mesh.num_nodes()).filter(|&i| sim.owns_node(i));
    let mass = sim.sum_over_processes(owned().map(|i| model.mass[i]).sum());
    let fall: f64 = owned()
        .map(|i| model.mass[i] * displacement(i).dot(&down))
        .sum();
    let drop = sim.sum_over_processes(fall) / mass;
    // A NaN drop (a body with no mass) is no fall either.
    if drop.is_nan() || drop <= FALL_LIMIT * size {
        return None;
    }
    let t = sim.state.time;
    let near = (0..mesh.num_nodes()).any(|i| {
        let x = mesh.rest[i] + displacement(i);
        obstacles.iter().any(|o| within(o, t, &x, size))
    });
    let near_anywhere = sim.max_over_processes(f64::from(u8::from(near))) > 0.0;
    (!near_anywhere).then_some((drop, drop / size))
}

/// Whether `x` (m) is within `reach` (m) of obstacle `o` at time `t` (s), or inside it.
fn within(o: &Obstacle, t: f64, x: &Vector3<f64>, reach: f64) -> bool {
    let x0 = o.motion.origin_of(t, x);
    match &o.shape {
        Shape::HalfSpace { point, normal } => (x0 - point).dot(normal) <= reach,
        Shape::Container { inner } => {
            let outside = (inner.min - x0)
                .sup(&(x0 - inner.max))
                .sup(&Vector3::zeros());
            outside.norm() <= reach
        }
        Shape::Mesh { surface } => surface.closest(x0, reach).is_some(),
    }
}

impl Outcome {
    /// The outcome as lines of text for the run's summary (warnings apart).
    pub fn lines(&self) -> Vec<String> {
        let mut lines = Vec::new();
        let mpa = |stress: f64| stress / 1e6;
        if let Some(f) = &self.fracture {
            if f.events > 0 {
                lines.push(format!(
                    "cracks: {} fracture events, crack area {:.3e} m²; the largest separation stress {:.3} MPa against the toughness {:.3} MPa",
                    f.events,
                    f.crack_area,
                    mpa(f.largest_stress),
                    mpa(f.toughness)
                ));
            } else if f.crack_area > 0.0 {
                // A resumed run: its cracks were made before it.
                lines.push(format!(
                    "cracks: no new fracture events, crack area {:.3e} m²; the largest separation stress {:.3} MPa against the toughness {:.3} MPa",
                    f.crack_area,
                    mpa(f.largest_stress),
                    mpa(f.toughness)
                ));
            } else {
                let capped = f.yield_stress.map_or(String::new(), |s| {
                    format!(
                        "; [plasticity] caps ice's deviatoric stress near 2 μ γ = {:.3} MPa",
                        mpa(s)
                    )
                });
                lines.push(format!(
                    "no cracks: the largest separation stress {:.3} MPa stayed below the toughness {:.3} MPa{capped}",
                    mpa(f.largest_stress),
                    mpa(f.toughness)
                ));
            }
        }
        if let Some(frozen) = self.frozen_fraction {
            lines.push(format!("frozen: {:.1} % of the volume", 100.0 * frozen));
        }
        if let Some(strain) = self.largest_inelastic_strain {
            lines.push(format!(
                "largest inelastic strain ‖ε_p‖ (plastic_strain_norm): {strain:.3e}"
            ));
        }
        lines
    }
}

#[cfg(test)]
mod tests {
    use super::{FractureOutcome, Outcome};

    #[test]
    fn a_run_without_new_splits_on_a_cracked_mesh_reports_its_cracks() {
        // A resumed run whose cracks were all made before it: not "no cracks".
        let fracture = |events, crack_area| FractureOutcome {
            events,
            crack_area,
            largest_stress: 2.363e6,
            toughness: 3e6,
            yield_stress: None,
        };
        let lines = |f| {
            let outcome = Outcome {
                fracture: Some(f),
                ..Outcome::default()
            };
            outcome.lines()
        };
        assert_eq!(
            lines(fracture(0, 2.222e-3)),
            ["cracks: no new fracture events, crack area 2.222e-3 m²; the largest separation stress 2.363 MPa against the toughness 3.000 MPa"]
        );
        assert!(lines(fracture(0, 0.0))[0].starts_with("no cracks: the largest separation"));
        assert!(lines(fracture(4, 2.222e-3))[0].starts_with("cracks: 4 fracture events"));
    }
}
