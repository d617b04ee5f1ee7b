//! Freezing: a front moving in from the cooling surfaces sets each element's freeze state,
//! which blends its material from water to ice and grows its expansion eigenstrain.
//!
//! The front leaves the cooling faces of a box (by default the mesh's bounding box: the water
//! body) at `start_time` with speed `front_speed`; it reaches a point at t_a = start + d / speed,
//! d being the distance from the point to the nearest cooling face. Ice there forms over
//! `transition_time`: local state clamp((t − t_a) / t_tr, 0, 1) (a step at t_a when t_tr = 0).
//! An element's state s is the mean of the local states at [`SAMPLES`] points spread evenly
//! through it (a lattice in barycentric coordinates, all inside): the share of its volume the
//! front has passed, so an element the front is crossing is partly frozen, and its state rises
//! over the time the front takes to cross it plus t_tr, in steps of 1/[`SAMPLES`] spread over
//! that time. Taking the state at the centroid instead would freeze every element of a layer
//! of a structured mesh in the same step (36 or 76 elements at once in the paper's scene), a
//! jump of load the fracture criterion reads as a burst of cracks; at its vertices, an
//! element with its four vertices on cooling faces (at the container's edges) would freeze
//! at once, while most of it is a cell away from the wall. With interior samples the load
//! grows with the front, and the frozen volume converges to the front's as the mesh is
//! refined. Its expansion is ε_exp = s e_max I with
//! e_max = ratio^(1/3) − 1 (water → ice: 1.09 in volume, e_max ≈ 0.0291), a strain offset that
//! never moves the rest mesh, so the element stiffness and its Jacobian stay exact. Its
//! stiffness is (1 − s) water + s ice (see `Elasticity::material_of`).
//!
//! Water carries pressure only (bulk modulus 2.2e9 Pa, energy K/2 (J − 1)²), or nothing
//! ("inactive"). Both get a small regularising shear modulus (default 1e-4 of the ice's): a
//! shear-free tet mesh has zero-energy modes that only inertia controls, m/h² ≈ 1e-2 N/m for
//! a gram of water at a frame-sized step against 1e9 N/m of ice, and Newton then proposes
//! steps of metres. At 1e-4 of the ice's stiffness the water's shear stresses stay 1e-4 of
//! the ice's, far below anything that matters for the ice, and the mesh of the liquid keeps
//! its shape.

use super::distance::SurfaceDistance;
use super::history::ElementHistory;
use super::thermal_strain::ThermalStrain;
use super::Region;
use crate::mesh::TetMesh;
use nalgebra::Vector3;
use rayon::prelude::*;

/// How unfrozen water behaves.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Water {
    /// Bulk-only: pressure from volume change with this bulk modulus (Pa), no shear stiffness,
    /// no plasticity, no fracture. Trapped water transmits pressure.
    Bulk { modulus: f64 },
    /// No stiffness at all until it freezes (it keeps its mass).
    Inactive,
}

/// Lattice order of the sample points: barycentric coordinates (i + ¼, j + ¼, k + ¼, l + ¼) /
/// (ORDER + 1) for i + j + k + l = ORDER.
const ORDER: usize = 4;

/// Sample points per element, (ORDER + 3 choose 3).
pub const SAMPLES: usize = 35;

/// The barycentric coordinates of the sample points.
fn sample_points() -> Vec<[f64; 4]> {
    let mut points = Vec::with_capacity(SAMPLES);
    let scale = 1.0 / (ORDER + 1) as f64;
    for i in 0..=ORDER {
        for j in 0..=ORDER - i {
            for k in 0..=ORDER - i - j {
                let l = ORDER - i - j - k;
                points.push([i, j, k, l].map(|c| (c as f64 + 0.25) * scale));
            }
        }
    }
    debug_assert_eq!(points.len(), SAMPLES);
    points
}

/// Which faces of the freezing box cool: −x, +x, −y, +y, −z (bottom), +z (top).
pub type CoolingFaces = [bool; 6];

/// Where the elements' freeze states come from.
#[derive(Clone, Debug, PartialEq)]
pub enum Schedule {
    /// A prescribed front.
    Front {
        /// Time the front reaches each sample point of each element (s); infinite if no face
        /// cools.
        arrival: Vec<[f64; SAMPLES]>,
        /// Time an element takes to freeze once the front arrives (s).
        transition: f64,
    },
    /// A heat solve ([`crate::thermal`]): each element's ice fraction and temperature at the
    /// start and the end of the current step, linear in time between them (halved substeps
    /// see the values in between).
    Thermal {
        /// The elements at the step's start.
        start: ThermalPoint,
        /// The elements at the step's end.
        end: ThermalPoint,
    },
}

/// The elements of a heat-driven run at one time.
#[derive(Clone, Debug, PartialEq)]
pub struct ThermalPoint {
    /// Time (s).
    pub time: f64,
    /// Ice fraction per element, 0 … 1.
    pub fraction: Vec<f64>,
    /// Temperature per element (°C): the mean of its nodes'.
    pub temperature: Vec<f64>,
}

impl ThermalPoint {
    /// `values` of the points `a` (at time a.time) and `b` (b.time) interpolated linearly to
    /// time `t` (s); `b`'s at and after b.time.
    fn between(a: &Self, b: &Self, t: f64, values: impl Fn(&Self) -> f64) -> f64 {
        if t >= b.time || b.time <= a.time {
            values(b)
        } else {
            let w = ((t - a.time) / (b.time - a.time)).clamp(0.0, 1.0);
            values(a) + w * (values(b) - values(a))
        }
    }

    /// The point on a split mesh whose element `e` came from element `parent[e]`.
    fn inherit(&self, parent: &[usize]) -> Self {
        ThermalPoint {
            time: self.time,
            fraction: take(&self.fraction, parent),
            temperature: take(&self.temperature, parent),
        }
    }
}

impl Schedule {
    /// Freeze state of element `e` at time `t` (s), 0 … 1: for a front, the mean of its sample
    /// points'; from a heat solve, its ice fraction interpolated over the step.
    pub fn state(&self, e: usize, t: f64) -> f64 {
        match self {
            Schedule::Front {
                arrival,
                transition,
            } => {
                let local = |arrival: f64| {
                    let since = t - arrival;
                    if *transition > 0.0 {
                        (since / transition).clamp(0.0, 1.0)
                    } else if since >= 0.0 {
                        1.0
                    } else {
                        0.0
                    }
                };
                let frozen = arrival[e].iter().map(|&a| local(a)).sum::<f64>();
                // Exactly 1 once every sample has frozen (the sum of ones is exact).
                frozen / SAMPLES as f64
            }
            Schedule::Thermal { start, end } => {
                ThermalPoint::between(start, end, t, |p| p.fraction[e])
            }
        }
    }

    /// Temperature of element `e` at time `t` (s) (°C), interpolated over the step; `None`
    /// for a prescribed front.
    pub fn temperature(&self, e: usize, t: f64) -> Option<f64> {
        match self {
            Schedule::Front { .. } => None,
            Schedule::Thermal { start, end } => {
                Some(ThermalPoint::between(start, end, t, |p| p.temperature[e]))
            }
        }
    }

    /// The schedule on a split mesh whose element `e` came from element `parent[e]`.
    pub fn inherit(&self, parent: &[usize]) -> Self {
        match self {
            Schedule::Front {
                arrival,
                transition,
            } => Schedule::Front {
                arrival: take(arrival, parent),
                transition: *transition,
            },
            Schedule::Thermal { start, end } => Schedule::Thermal {
                start: start.inherit(parent),
                end: end.inherit(parent),
            },
        }
    }
}

/// The values of `v` per element of a split mesh whose element `e` came from `parent[e]`.
fn take<T: Copy>(v: &[T], parent: &[usize]) -> Vec<T> {
    parent.iter().map(|&p| v[p]).collect()
}

/// The freezing schedule of every element.
#[derive(Clone, Debug, PartialEq)]
pub struct Freezing {
    /// Where the freeze states come from.
    pub schedule: Schedule,
    /// Largest expansion eigenstrain e_max = ratio^(1/3) − 1 (dimensionless).
    pub expansion: f64,
    /// The water model.
    pub water: Water,
    /// Regularising shear modulus of unfrozen water (Pa).
    pub water_shear: f64,
    /// Eigenstrain of each element without freezing (from the scene), added to the expansion.
    pub base_eigenstrain: Vec<f64>,
    /// The ice's thermal strain, for a heat-driven schedule with a thermal expansion
    /// coefficient (none: ice keeps its size at every temperature).
    pub thermal_strain: Option<ThermalStrain>,
    /// Ice fraction each element starts with (empty: none, as for a front). The mesh is
    /// the shape of the material it starts as: ice present at the start does not expand, ice
    /// formed later does, and ice that melts shrinks back (expansion (s − s₀) e_max).
    pub initial_ice: Vec<f64>,
    /// Whether the ice's expansion goes into the water (`ice_formation`) rather than into
    /// each freezing element's eigenstrain.
    pub displaces_water: bool,
}

impl Freezing {
    /// A front from the `cooling` faces of `region` at `speed` (m/s) from `start` (s). The
    /// water's shear regularisation starts at 0; scenes set `water_shear` (default 1e-4 μ).
    // The arguments are the schedule's independent physical inputs.
    #[allow(clippy::too_many_arguments)]
    pub fn from_front(
        mesh: &TetMesh,
        region: &Region,
        cooling: CoolingFaces,
        speed: f64,
        start: f64,
        transition: f64,
        expansion_ratio: f64,
        water: Water,
    ) -> Self {
        let arrival_at = |c: Vector3<f64>| {
            let distance = (0..6)
                .filter(|&f| cooling[f])
                .map(|f| {
                    let a = f / 2;
                    if f % 2 == 0 {
                        c[a] - region.min[a]
                    } else {
                        region.max[a] - c[a]
                    }
                })
                .fold(f64::INFINITY, f64::min)
                .max(0.0);
            start + distance / speed
        };
        Self::from_arrival(
            mesh,
            |_, points| points.iter().map(|&x| arrival_at(x)).collect(),
            transition,
            expansion_ratio,
            water,
        )
    }

    /// A front from the surface `triangles` (node triples of `mesh`, e.g. all its boundary
    /// faces) at `speed` (m/s) from `start` (s), the distance measured through the mesh (see
    /// [`SurfaceDistance`]): a sphere freezes from its surface inward.
    pub fn from_surface(
        mesh: &TetMesh,
        triangles: &[[usize; 3]],
        (speed, start, transition): (f64, f64, f64),
        expansion_ratio: f64,
        water: Water,
    ) -> Self {
        let distance = SurfaceDistance::new(mesh, triangles);
        Self::from_arrival(
            mesh,
            |tet, points| {
                distance
                    .at_points(tet, points)
                    .into_iter()
                    .map(|d| start + d / speed)
                    .collect()
            },
            transition,
            expansion_ratio,
            water,
        )
    }

    /// The schedule with the front reaching the `points` of the element with nodes `tet` at
    /// the times `arrival_at(tet, points)` (s).
    fn from_arrival(
        mesh: &TetMesh,
        arrival_at: impl Fn(&[usize; 4], &[Vector3<f64>]) -> Vec<f64> + Sync,
        transition: f64,
        expansion_ratio: f64,
        water: Water,
    ) -> Self {
        let samples = sample_points();
        let arrival = mesh
            .tets
            .par_iter()
            .map(|tet| {
                let x = tet.map(|v| mesh.rest[v]);
                let points: Vec<Vector3<f64>> = samples
                    .iter()
                    .map(|b| x[0] * b[0] + x[1] * b[1] + x[2] * b[2] + x[3] * b[3])
                    .collect();
                let mut times = [0.0; SAMPLES];
                times.copy_from_slice(&arrival_at(tet, &points));
                times
            })
            .collect();
        Freezing {
            schedule: Schedule::Front {
                arrival,
                transition,
            },
            expansion: expansion_ratio.cbrt() - 1.0,
            water,
            water_shear: 0.0,
            base_eigenstrain: vec![0.0; mesh.num_tets()],
            thermal_strain: None,
            initial_ice: Vec::new(),
            displaces_water: false,
        }
    }

    /// Freezing driven by a heat solve, every element as `at` gives it (ice fraction and
    /// temperature at its time) until the first step sets the next; the ice it holds there is
    /// the initial ice; the expansion and water as [`Self::from_front`].
    pub fn thermal(at: ThermalPoint, expansion_ratio: f64, water: Water) -> Self {
        let n = at.fraction.len();
        Freezing {
            initial_ice: at.fraction.clone(),
            schedule: Schedule::Thermal {
                start: at.clone(),
                end: at,
            },
            expansion: expansion_ratio.cbrt() - 1.0,
            water,
            water_shear: 0.0,
            base_eigenstrain: vec![0.0; n],
            thermal_strain: None,
            displaces_water: false,
        }
    }

    /// Freeze state of element `e` at time `t` (s), 0 … 1: for a front, the mean of its sample
    /// points'; from a heat solve, its ice fraction interpolated over the step.
    pub fn state(&self, e: usize, t: f64) -> f64 {
        self.schedule.state(e, t)
    }

    /// The front's arrival times per element and sample (s), for a prescribed front.
    pub fn arrival(&self) -> Option<&[[f64; SAMPLES]]> {
        match &self.schedule {
            Schedule::Front { arrival, .. } => Some(arrival),
            Schedule::Thermal { .. } => None,
        }
    }

    /// The schedule on a split mesh whose element `e` came from element `parent[e]`.
    pub fn inherit(&self, parent: &[usize]) -> Self {
        Freezing {
            schedule: self.schedule.inherit(parent),
            base_eigenstrain: take(&self.base_eigenstrain, parent),
            thermal_strain: self.thermal_strain.as_ref().map(|t| t.inherit(parent)),
            initial_ice: if self.initial_ice.is_empty() {
                Vec::new()
            } else {
                take(&self.initial_ice, parent)
            },
            ..self.clone()
        }
    }

    /// The water's bulk modulus (Pa; 0 for inactive water).
    pub fn water_bulk(&self) -> f64 {
        match self.water {
            Water::Bulk { modulus } => modulus,
            Water::Inactive => 0.0,
        }
    }

    /// Sets every element's freeze state and eigenstrain in `history` for time `t` (s), the
    /// freeze states (and temperatures) those of `schedule` (this freezing's own, or a heat
    /// solve's over the current step). The eigenstrain of an element whose ice fraction is s
    /// (s₀ at the start) is its base eigenstrain plus (s − s₀) e_max + s ε_th: the water's
    /// share neither expands nor contracts with temperature. Where the ice displaces water
    /// the expansion is left out here (`ice_formation` gives it to the water).
    pub fn apply(&self, schedule: &Schedule, t: f64, history: &mut ElementHistory) {
        let n = self.base_eigenstrain.len();
        history.freeze_state.resize(n, 0.0);
        for e in 0..n {
            let s = schedule.state(e, t);
            let thermal = (self.thermal_strain.as_ref())
                .and_then(|strain| Some(strain.strain(e, schedule.temperature(e, t)?)))
                .unwrap_or(0.0);
            history.freeze_state[e] = s;
            let formed = s - self.initial_ice.get(e).copied().unwrap_or(0.0);
            let expansion = if self.displaces_water {
                0.0
            } else {
                formed * self.expansion
            };
            history.eigenstrain[e] = self.base_eigenstrain[e] + expansion + s * thermal;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::physics::thermal_strain::{Expansion, ThermalStrain};

    #[test]
    fn ice_from_the_start_keeps_its_shape_and_ice_formed_later_expands_and_contracts() {
        // Element 0 starts as ice at −5 °C, element 1 as water at +1 °C.
        let at = ThermalPoint {
            time: 0.0,
            fraction: vec![1.0, 0.0],
            temperature: vec![-5.0, 1.0],
        };
        let alpha = 5e-5;
        let mut freezing = Freezing::thermal(at.clone(), 1.09, Water::Inactive);
        freezing.thermal_strain = Some(ThermalStrain::new(
            Expansion::Constant(alpha),
            &at.fraction,
            &at.temperature,
            0.0,
        ));
        // A step of 10 s to both at −10 °C, element 1 half frozen.
        let end = ThermalPoint {
            time: 10.0,
            fraction: vec![1.0, 0.5],
            temperature: vec![-10.0, -10.0],
        };
        let schedule = Schedule::Thermal { start: at, end };
        let mut history = ElementHistory::initial(&[0.0, 0.0], false);
        let e_max = freezing.expansion;
        freezing.apply(&schedule, 10.0, &mut history);
        // Element 0: no expansion, α (−10 − (−5)); element 1: half its ice formed, born at 0 °C.
        let expected = [alpha * -5.0, 0.5 * e_max + 0.5 * alpha * -10.0];
        for (e, x) in history.eigenstrain.iter().zip(expected) {
            assert!((e - x).abs() < 1e-17, "{e} vs {x}");
        }
        // Halfway through the step: fractions and temperatures halfway.
        freezing.apply(&schedule, 5.0, &mut history);
        let halfway = [alpha * (-7.5 + 5.0), 0.25 * e_max + 0.25 * alpha * -4.5];
        for (e, x) in history.eigenstrain.iter().zip(halfway) {
            assert!((e - x).abs() < 1e-17, "{e} vs {x}");
        }
        // Split: new element 2 copies element 0, element 3 element 1.
        let parent = [0, 1, 0, 1];
        let (split, schedule) = (freezing.inherit(&parent), schedule.inherit(&parent));
        let mut history = ElementHistory::initial(&[0.0; 4], false);
        split.apply(&schedule, 10.0, &mut history);
        for (e, &p) in parent.iter().enumerate() {
            assert_eq!(history.eigenstrain[e].to_bits(), expected[p].to_bits());
        }
    }
}
