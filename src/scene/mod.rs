//! Scene files: the TOML schema (`SceneFile`, raw, as written) and its validation into a
//! [`Scene`] (checked, SI units, ready to simulate). Every error names the file and the field.
//!
//! ```toml
//! [mesh]
//! box = { size = [0.4, 0.04, 0.04], cells = [20, 2, 2] }   # or: file = "beam.msh"
//! [material]
//! density = 916.0          # kg/m³
//! lambda = 8.64e10         # Pa   (or youngs_modulus + poisson_ratio)
//! mu = 3.70e10             # Pa
//! model = "corotated"      # or "linear"
//! [physics]
//! gravity = [0.0, 0.0, -9.81]
//! [[dirichlet]]
//! min = [-1.0, -1.0, -1.0]
//! max = [0.0, 1.0, 1.0]
//! [time]
//! analysis = "dynamic"     # or "static"
//! dt = 0.0333333333
//! end_time = 1.0
//! ```

use crate::fem::{ElasticModel, Material};
use crate::fracture::FractureSettings;
use crate::mesh::surface::TriSurface;
use crate::mesh::{box_mesh, gmsh, MeshError, TetMesh};
use crate::physics::contact::Shape;
use crate::physics::elasticity::Volumetric;
use crate::physics::ice_contact::IceContactTerm;
use crate::physics::obstacle_mesh::ObstacleSurface;
use crate::physics::plasticity::Plasticity;
use crate::physics::{
    Amplitude, Contact, Dirichlet, Elasticity, Group, Model, Motion, Obstacle, Rayleigh, Region,
    Selection, Traction,
};
use crate::sim::{Analysis, StepSettings};
use crate::solver::{FactorPrecision, FillOrdering, LinearSolverKind, NewtonParams};
use nalgebra::Vector3;
use serde::Deserialize;
use std::path::{Path, PathBuf};
use std::sync::Arc;

mod bodies;
mod checks;
mod freezing;

pub use bodies::{BodySection, InitialSection, RotateSection};
pub use freezing::FreezingSection;

/// A scene that could not be read or is not valid.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The scene file could not be read.
    #[error("cannot read scene file {path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// TOML syntax error, unknown key or wrong type (the message names line and key).
    #[error("scene file {path}: {message}")]
    Parse { path: PathBuf, message: String },
    /// A value is missing or out of its allowed range.
    #[error("scene file {path}: field `{field}`: {message}")]
    Invalid {
        path: PathBuf,
        field: String,
        message: String,
    },
    /// The mesh file could not be read.
    #[error("scene file {path}: field `mesh.file`: {source}")]
    MeshFile {
        path: PathBuf,
        #[source]
        source: gmsh::GmshError,
    },
    /// An obstacle's surface file could not be read or is not valid.
    #[error("scene file {path}: field `{field}`: {source}")]
    SurfaceFile {
        path: PathBuf,
        field: String,
        #[source]
        source: crate::mesh::surface::SurfaceError,
    },
    /// The mesh is not valid.
    #[error("scene file {path}: field `mesh`: {source}")]
    Mesh {
        path: PathBuf,
        #[source]
        source: MeshError,
    },
}

/// The scene file as written (all fields optional where a default exists).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneFile {
    /// Mesh source (or `body`).
    pub mesh: Option<MeshSection>,
    /// Bodies, each placed and set moving (or `mesh`).
    #[serde(default)]
    pub body: Vec<BodySection>,
    /// Initial displacement and velocity from a frame of an earlier run on the same mesh.
    pub initial: Option<InitialSection>,
    /// Material.
    pub material: MaterialSection,
    /// Further materials by name, for bodies and regions that name them.
    #[serde(default)]
    pub materials: std::collections::BTreeMap<String, MaterialSection>,
    /// Physics terms.
    #[serde(default)]
    pub physics: PhysicsSection,
    /// Dirichlet conditions.
    #[serde(default)]
    pub dirichlet: Vec<DirichletSection>,
    /// Surface tractions.
    #[serde(default)]
    pub traction: Vec<TractionSection>,
    /// Fixed isotropic eigenstrains in regions.
    #[serde(default)]
    pub eigenstrain: Vec<EigenstrainSection>,
    /// Rigid obstacles the ice touches (penalty contact with friction).
    #[serde(default)]
    pub obstacle: Vec<ObstacleSection>,
    /// Freezing schedule (off if absent).
    pub freezing: Option<FreezingSection>,
    /// Plasticity (off if absent).
    pub plasticity: Option<PlasticitySection>,
    /// Brittle fracture (off if absent).
    pub fracture: Option<FractureSection>,
    /// Time stepping.
    pub time: TimeSection,
    /// Solver settings.
    #[serde(default)]
    pub solver: SolverSection,
    /// Output settings.
    #[serde(default)]
    pub output: OutputSection,
}

/// `[mesh]`: a built-in box or a Gmsh file.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MeshSection {
    /// Built-in box generator.
    #[serde(rename = "box")]
    pub box_: Option<BoxSection>,
    /// Several separate boxes (separate bodies in contact with each other).
    pub boxes: Option<Vec<BoxSection>>,
    /// Gmsh `.msh` file, relative to the scene file.
    pub file: Option<String>,
    /// Factor applied to file coordinates to get metres (e.g. 0.001 for mm). Default 1.
    pub scale: Option<f64>,
}

/// `[mesh.box]`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BoxSection {
    /// Lower corner (m). Default 0.
    #[serde(default)]
    pub origin: [f64; 3],
    /// Edge lengths (m).
    pub size: [f64; 3],
    /// Cells per axis.
    pub cells: [usize; 3],
    /// 5 or 6 tets per cell. Default 6.
    pub tets_per_cell: Option<usize>,
}

/// `[material]`, and `[materials.NAME]`: a material other than `[material]` (which sets the
/// strain measure and volumetric discretisation for all), for the `[[body]]` entries that name
/// it and for the elements of `region` or of the box `min`–`max` (these override bodies').
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialSection {
    /// ρ (kg/m³).
    pub density: f64,
    /// λ (Pa); give with `mu`.
    pub lambda: Option<f64>,
    /// μ (Pa); give with `lambda`.
    pub mu: Option<f64>,
    /// E (Pa); give with `poisson_ratio`.
    pub youngs_modulus: Option<f64>,
    /// ν; give with `youngs_modulus`.
    pub poisson_ratio: Option<f64>,
    /// Strain measure, default corotated.
    pub model: Option<ElasticModel>,
    /// Volumetric discretisation, `"element"` (default) or `"nodal"` (average nodal
    /// pressure: no volumetric locking).
    pub volumetric: Option<Volumetric>,
    /// `[materials.NAME]` only: a named physical volume of the mesh file whose elements are of
    /// this material.
    pub region: Option<String>,
    /// `[materials.NAME]` only: box lower corner (m); elements whose centroid is in the box
    /// are of this material.
    pub min: Option<[f64; 3]>,
    /// `[materials.NAME]` only: box upper corner (m).
    pub max: Option<[f64; 3]>,
}

/// `[physics]`.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PhysicsSection {
    /// Gravity (m/s²), default zero.
    pub gravity: Option<[f64; 3]>,
    /// Amplitude of gravity in time: [time (s), factor] points. Default 1.
    pub gravity_amplitude: Option<Vec<[f64; 2]>>,
    /// Rayleigh damping.
    pub damping: Option<DampingSection>,
    /// Friction smoothing velocity ε_v (m/s): slower relative sliding counts as sticking.
    /// Default 1e-4.
    pub friction_smoothing_velocity: Option<f64>,
    /// Coulomb friction coefficient between separate pieces of ice. Default 0.
    pub ice_friction: Option<f64>,
    /// Penalty stiffness between separate pieces of ice (N/m³). Default 10 E / h.
    pub ice_stiffness: Option<f64>,
}

/// `[physics.damping]`: D = α M + β K.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DampingSection {
    /// α (1/s).
    #[serde(default)]
    pub mass: f64,
    /// β (s).
    #[serde(default)]
    pub stiffness: f64,
}

/// `[[dirichlet]]`: nodes in the box `min`–`max` (or of the named group `region`) prescribed
/// on `axes`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DirichletSection {
    /// Box lower corner (m).
    pub min: Option<[f64; 3]>,
    /// Box upper corner (m).
    pub max: Option<[f64; 3]>,
    /// A named physical group of the mesh file (volume or surface), instead of the box.
    pub region: Option<String>,
    /// Constrained axes, a subset of "xyz". Default "xyz".
    pub axes: Option<String>,
    /// Displacement at t = 0 (m). Default 0.
    pub displacement: Option<[f64; 3]>,
    /// Prescribed velocity (m/s). Default 0.
    pub velocity: Option<[f64; 3]>,
    /// Amplitude of `displacement` in time: [time (s), factor] points. Default 1.
    pub amplitude: Option<Vec<[f64; 2]>>,
}

/// `[[traction]]`: a traction on the boundary faces whose centroid is in the box (or on the
/// named surface `region`).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TractionSection {
    /// Box lower corner (m).
    pub min: Option<[f64; 3]>,
    /// Box upper corner (m).
    pub max: Option<[f64; 3]>,
    /// A named physical surface of the mesh file, instead of the box.
    pub region: Option<String>,
    /// Traction (Pa).
    pub traction: [f64; 3],
    /// Amplitude of the traction in time: [time (s), factor] points. Default 1.
    pub amplitude: Option<Vec<[f64; 2]>>,
}

/// `[[eigenstrain]]`: a fixed isotropic eigenstrain e (σ = C : (ε − e I)) in the elements
/// whose rest centroid lies in the box (or in the named volume `region`). Later entries
/// override earlier ones.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EigenstrainSection {
    /// Box lower corner (m).
    pub min: Option<[f64; 3]>,
    /// Box upper corner (m).
    pub max: Option<[f64; 3]>,
    /// A named physical volume of the mesh file, instead of the box.
    pub region: Option<String>,
    /// e (dimensionless), in (−0.5, 0.5).
    pub value: f64,
}

/// `[[obstacle]]`: a rigid obstacle, `type = "halfspace"` (with `point`, `normal`),
/// `type = "container"` (open-top box with inner corners `min`, `max`) or `type = "mesh"`
/// (a triangle surface from `file`, OBJ or Gmsh, times `scale`, moved by `translate`).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObstacleSection {
    /// "halfspace", "container" or "mesh".
    #[serde(rename = "type")]
    pub kind: String,
    /// Mesh: surface file (.obj or .msh), relative to the scene file.
    pub file: Option<PathBuf>,
    /// Mesh: factor applied to the file's coordinates (to metres). Default 1.
    pub scale: Option<f64>,
    /// Mesh: translation applied after scaling (m). Default 0.
    pub translate: Option<[f64; 3]>,
    /// Half-space: a point on its surface (m).
    pub point: Option<[f64; 3]>,
    /// Half-space: normal pointing out of the obstacle (normalised here).
    pub normal: Option<[f64; 3]>,
    /// Container: inner lower corner (m).
    pub min: Option<[f64; 3]>,
    /// Container: inner upper corner (m); its z is the rim (the top is open).
    pub max: Option<[f64; 3]>,
    /// Rigid velocity (m/s). Default 0.
    pub velocity: Option<[f64; 3]>,
    /// Angular velocity (rad/s) about `centre`. Default 0.
    pub angular_velocity: Option<[f64; 3]>,
    /// The point the obstacle turns about at t = 0 (m); it moves with `velocity`. Default 0.
    pub centre: Option<[f64; 3]>,
    /// Amplitude of `velocity` and `angular_velocity` in time: [time (s), factor] points.
    /// Default 1.
    pub amplitude: Option<Vec<[f64; 2]>>,
    /// Penalty stiffness (N/m³). Default 10 E / h (h: mean boundary edge length of the ice).
    pub stiffness: Option<f64>,
    /// Coulomb friction coefficient. Default 0.
    pub friction: Option<f64>,
}

/// `[plasticity]`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlasticitySection {
    /// Elastic limit γ: the deviatoric elastic strain norm above which ice yields.
    pub elastic_limit: f64,
    /// Cap on the plastic strain norm. Default: none.
    pub max_plastic_strain: Option<f64>,
}

/// `[fracture]`: O'Brien–Hodgins node splitting between steps (see `fracture::driver`).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FractureSection {
    /// Toughness as a stress (Pa): a node splits when v⁺ / A(n) exceeds it.
    pub toughness: f64,
    /// Most node splits per time step. Default 8.
    pub max_events_per_step: Option<usize>,
    /// Fraction of an edge within which a crack snaps to the edge's end, [0, 0.5). Default 0.2.
    pub snap: Option<f64>,
    /// Smallest radius ratio a split may create, [0, 1). Default 0.1.
    pub min_quality: Option<f64>,
    /// Smallest opening drawn between crack sides in the output (m). Default 1e-3 × the
    /// mesh's bounding-box diagonal.
    pub render_gap: Option<f64>,
    /// Length ℓ (m) over which the separation is averaged (`fracture::nonlocal`); 0 or absent:
    /// each node on its own, as in the paper.
    pub nonlocal_length: Option<f64>,
}

/// `[time]`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TimeSection {
    /// Static or dynamic; default dynamic.
    pub analysis: Option<Analysis>,
    /// Time step (s).
    pub dt: f64,
    /// End time (s).
    pub end_time: f64,
    /// Write a frame every this many steps. Default 1.
    pub output_every: Option<u64>,
}

/// `[solver]`.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SolverSection {
    /// "auto" (default: Cholesky up to `AUTO_DIRECT_MAX_DOFS` free dofs, multigrid CG above),
    /// "cholesky", "cg" (Jacobi-preconditioned) or "amg" (multigrid-preconditioned CG).
    pub linear: Option<LinearSolverKind>,
    /// Cholesky ordering: "auto" (default), "amd" or "metis".
    pub ordering: Option<FillOrdering>,
    /// Newton relative residual tolerance. Default 1e-9.
    pub tolerance: Option<f64>,
    /// Newton iteration cap. Default 50.
    pub max_iterations: Option<usize>,
    /// CG relative tolerance. Default 1e-12.
    pub cg_tolerance: Option<f64>,
    /// CG iteration cap. Default 20000.
    pub cg_max_iterations: Option<usize>,
    /// Keep the multigrid hierarchy across Newton iterations and steps until CG's iterations
    /// grow by half (true, default), or set it up at every Hessian refresh (false).
    pub amg_reuse: Option<bool>,
    /// Cholesky: keep a factorisation across Hessian refreshes and steps as the preconditioner
    /// of CG until that needs more than 5 iterations per decade of residual reduction (true),
    /// or factorise at every refresh (false, default: results then do not depend on the
    /// history, and resumed runs are bit-identical).
    pub reuse_factorization: Option<bool>,
    /// Precision of the kept factorisation: "single" (default: half the memory, a third less
    /// time per factorisation, double precision automatically where single fails) or "double".
    pub factor_precision: Option<FactorPrecision>,
}

/// `[output]`.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OutputSection {
    /// HDF5 file, relative to the working directory. Default: the scene's name with `.h5`.
    pub file: Option<String>,
}

/// A validated scene.
#[derive(Clone, Debug)]
pub struct Scene {
    /// Where it was read from.
    pub path: PathBuf,
    /// The scene text (stored in the output).
    pub text: String,
    /// The mechanics.
    pub model: Model,
    /// Stepping and solver settings.
    pub settings: StepSettings,
    /// End time (s).
    pub end_time: f64,
    /// Steps per output frame.
    pub output_every: u64,
    /// Default output file.
    pub output: PathBuf,
    /// Fracture, if on.
    pub fracture: Option<FractureSettings>,
    /// What the user should know about the input that is not an error (one line each), such
    /// as mesh elements that were reoriented.
    pub notices: Vec<String>,
}

impl Scene {
    /// Reads and validates a scene file.
    pub fn load(path: &Path) -> Result<Scene, SceneError> {
        let text = std::fs::read_to_string(path).map_err(|source| SceneError::Io {
            path: path.into(),
            source,
        })?;
        Scene::parse(&text, path)
    }

    /// Validates scene `text` as if read from `path` (mesh files are relative to its folder).
    pub fn parse(text: &str, path: &Path) -> Result<Scene, SceneError> {
        let raw: SceneFile = toml::from_str(text).map_err(|e| SceneError::Parse {
            path: path.into(),
            message: e.to_string(),
        })?;
        Validator {
            path,
            notices: Default::default(),
            groups: Default::default(),
        }
        .scene(raw, text)
    }
}

struct Validator<'a> {
    path: &'a Path,
    /// What the user should know about the input that is not an error.
    notices: std::cell::RefCell<Vec<String>>,
    /// The mesh files' named physical groups, placed as the scene places the mesh.
    groups: std::cell::RefCell<Vec<Arc<Group>>>,
}

impl Validator<'_> {
    /// A time function from its `[time (s), factor]` points (1 throughout if absent).
    fn amplitude(
        &self,
        field: &str,
        points: &Option<Vec<[f64; 2]>>,
    ) -> Result<Amplitude, SceneError> {
        match points {
            None => Ok(Amplitude::default()),
            Some(points) => Amplitude::new(points.iter().map(|&[t, a]| (t, a)).collect())
                .map_err(|message| self.invalid(field, message)),
        }
    }

    fn invalid(&self, field: &str, message: impl Into<String>) -> SceneError {
        SceneError::Invalid {
            path: self.path.into(),
            field: field.into(),
            message: message.into(),
        }
    }

    fn finite(&self, field: &str, v: f64) -> Result<f64, SceneError> {
        if v.is_finite() {
            Ok(v)
        } else {
            Err(self.invalid(field, format!("must be a finite number, got {v}")))
        }
    }

    fn positive(&self, field: &str, v: f64) -> Result<f64, SceneError> {
        if v.is_finite() && v > 0.0 {
            Ok(v)
        } else {
            Err(self.invalid(field, format!("must be finite and > 0, got {v}")))
        }
    }

    fn non_negative(&self, field: &str, v: f64) -> Result<f64, SceneError> {
        if v.is_finite() && v >= 0.0 {
            Ok(v)
        } else {
            Err(self.invalid(field, format!("must be finite and ≥ 0, got {v}")))
        }
    }

    fn vector(&self, field: &str, v: [f64; 3]) -> Result<Vector3<f64>, SceneError> {
        for (a, c) in v.iter().enumerate() {
            self.finite(&format!("{field}[{a}]"), *c)?;
        }
        Ok(Vector3::from(v))
    }

    fn region(&self, field: &str, min: [f64; 3], max: [f64; 3]) -> Result<Region, SceneError> {
        let region = Region {
            min: self.vector(&format!("{field}.min"), min)?,
            max: self.vector(&format!("{field}.max"), max)?,
        };
        if (0..3).any(|a| region.min[a] > region.max[a]) {
            return Err(self.invalid(
                &format!("{field}.min"),
                format!("must be ≤ max on every axis, got min {min:?}, max {max:?}"),
            ));
        }
        Ok(region)
    }

    /// Where an entry applies: the box `min`–`max` or the named group `region` (of dimension
    /// `dim`: 2 surfaces, 3 volumes; `None`: either).
    fn selection(
        &self,
        field: &str,
        (min, max, region): (Option<[f64; 3]>, Option<[f64; 3]>, Option<&String>),
        dim: Option<u8>,
    ) -> Result<Selection, SceneError> {
        match (min, max, region) {
            (Some(min), Some(max), None) => Ok(Selection::Box(self.region(field, min, max)?)),
            (None, None, Some(name)) => {
                let groups = self.groups.borrow();
                let listing = || {
                    let names: Vec<String> = groups
                        .iter()
                        .map(|g| format!("{:?} ({})", g.name, kind_name(g.dim)))
                        .collect();
                    if names.is_empty() {
                        "the mesh has no named physical groups".to_string()
                    } else {
                        format!("the mesh's groups: {}", names.join(", "))
                    }
                };
                let group = groups.iter().find(|g| &g.name == name).ok_or_else(|| {
                    self.invalid(
                        &format!("{field}.region"),
                        format!("no physical group {name:?}; {}", listing()),
                    )
                })?;
                match dim {
                    Some(d) if d != group.dim => Err(self.invalid(
                        &format!("{field}.region"),
                        format!(
                            "{name:?} is a {}; this entry needs a {}",
                            kind_name(group.dim),
                            kind_name(d)
                        ),
                    )),
                    _ => Ok(Selection::Group(group.clone())),
                }
            }
            (_, _, Some(_)) => Err(self.invalid(
                &format!("{field}.region"),
                "give a named `region` or a box `min`/`max`, not both",
            )),
            _ => Err(self.invalid(
                field,
                "give a box (`min` and `max`, m) or a named `region` (a physical group of the mesh file)",
            )),
        }
    }

    fn scene(&self, raw: SceneFile, text: &str) -> Result<Scene, SceneError> {
        let (mesh, initial_velocity, body_elements) = match (&raw.mesh, raw.body.is_empty()) {
            (Some(m), true) => (self.mesh(m)?, Vec::new(), Vec::new()),
            (None, false) => {
                let b = self.bodies(&raw.body)?;
                (b.mesh, b.velocity, b.elements)
            }
            (Some(_), false) => {
                return Err(self.invalid("body", "give `[mesh]` or `[[body]]` entries, not both"))
            }
            (None, true) => {
                return Err(self.invalid("mesh", "missing: give `[mesh]` or `[[body]]` entries"))
            }
        };
        let (material, model) = self.material(&raw.material)?;
        let gravity = self.vector("physics.gravity", raw.physics.gravity.unwrap_or_default())?;
        let damping = match &raw.physics.damping {
            Some(d) => Some(Rayleigh {
                mass: self.non_negative("physics.damping.mass", d.mass)?,
                stiffness: self.non_negative("physics.damping.stiffness", d.stiffness)?,
            }),
            None => None,
        };
        let dirichlet = raw
            .dirichlet
            .iter()
            .enumerate()
            .map(|(i, d)| self.dirichlet(i, d))
            .collect::<Result<Vec<_>, _>>()?;
        let mut tractions = Vec::new();
        for (i, t) in raw.traction.iter().enumerate() {
            let field = format!("traction[{i}]");
            let region = self.selection(&field, (t.min, t.max, t.region.as_ref()), Some(2))?;
            let traction = Traction {
                region: region.clone(),
                traction: self.vector(&format!("{field}.traction"), t.traction)?,
                amplitude: self.amplitude(&format!("{field}.amplitude"), &t.amplitude)?,
            };
            if crate::physics::loads::traction_faces(&mesh, &region).0 == 0 {
                return Err(self.invalid(
                    &field,
                    format!(
                        "the {} contains no boundary-face centroid of the mesh",
                        region.describe()
                    ),
                ));
            }
            tractions.push(traction);
        }
        let time = &raw.time;
        let dt = self.positive("time.dt", time.dt)?;
        let end_time = self.positive("time.end_time", time.end_time)?;
        let output_every = time.output_every.unwrap_or(1);
        if output_every == 0 {
            return Err(self.invalid("time.output_every", "must be ≥ 1"));
        }
        let solver = &raw.solver;
        let tolerance = solver.tolerance.unwrap_or(1e-9);
        if !(tolerance > 0.0 && tolerance < 1.0) {
            return Err(self.invalid(
                "solver.tolerance",
                format!("must be in (0, 1), got {tolerance}"),
            ));
        }
        let cg_tolerance = solver.cg_tolerance.unwrap_or(1e-12);
        if !(cg_tolerance > 0.0 && cg_tolerance < 1.0) {
            return Err(self.invalid(
                "solver.cg_tolerance",
                format!("must be in (0, 1), got {cg_tolerance}"),
            ));
        }
        let max_iterations = solver.max_iterations.unwrap_or(50);
        if max_iterations == 0 {
            return Err(self.invalid("solver.max_iterations", "must be ≥ 1"));
        }
        let cg_max_iterations = solver.cg_max_iterations.unwrap_or(20_000);
        if cg_max_iterations == 0 {
            return Err(self.invalid("solver.cg_max_iterations", "must be ≥ 1"));
        }
        let (lo, hi) = mesh.bounding_box();
        let settings = StepSettings {
            analysis: time.analysis.unwrap_or(Analysis::Dynamic),
            dt,
            newton: NewtonParams {
                tolerance,
                // An update of 1e-15 of the body size is at the round-off of the positions.
                step_tolerance: 1e-15 * (hi - lo).norm(),
                max_iterations,
            },
            linear: solver.linear.unwrap_or(LinearSolverKind::Auto),
            ordering: solver.ordering.unwrap_or(FillOrdering::Auto),
            cg_tolerance,
            cg_max_iterations,
            amg_reuse: solver.amg_reuse.unwrap_or(true),
            factor_reuse: solver.reuse_factorization.unwrap_or(false),
            factor_precision: solver.factor_precision.unwrap_or(FactorPrecision::Single),
        };
        let mut elasticity = Elasticity::new(&mesh, material, model);
        self.other_materials(&raw, &mesh, &body_elements, &mut elasticity)?;
        elasticity.set_volumetric(&mesh, raw.material.volumetric.unwrap_or_default());
        for (i, section) in raw.eigenstrain.iter().enumerate() {
            let field = format!("eigenstrain[{i}]");
            let region = self.selection(
                &field,
                (section.min, section.max, section.region.as_ref()),
                Some(3),
            )?;
            let e = section.value;
            // Physical eigenstrains are a few percent; beyond ±0.5 the small-strain reading of
            // σ = C:(ε − e I) and the multiplicative corotated form part ways.
            if !(e.is_finite() && e.abs() < 0.5) {
                return Err(self.invalid(
                    &format!("{field}.value"),
                    format!("must be in (−0.5, 0.5), got {e}"),
                ));
            }
            for t in self.selected_elements(&field, &mesh, &region)? {
                elasticity.eigenstrain[t] = e;
            }
        }
        let obstacles = raw
            .obstacle
            .iter()
            .enumerate()
            .map(|(i, o)| self.obstacle(i, o, &mesh, &material))
            .collect::<Result<Vec<_>, _>>()?;
        self.check_outside_obstacles(&mesh, &obstacles)?;
        let smoothing = self.positive(
            "physics.friction_smoothing_velocity",
            raw.physics.friction_smoothing_velocity.unwrap_or(1e-4),
        )?;
        let contact = (!obstacles.is_empty()).then(|| Contact::new(&mesh, obstacles, smoothing));
        let mut model = Model::new(mesh, elasticity, gravity, &tractions, damping, dirichlet)
            .map_err(|source| SceneError::Mesh {
                path: self.path.into(),
                source,
            })?;
        let (initial_displacement, initial_velocity) = match &raw.initial {
            None => (Vec::new(), initial_velocity),
            Some(_) if !initial_velocity.is_empty() => {
                return Err(self.invalid(
                    "initial",
                    "give initial velocities by `[[body]]` entries or by `[initial]`, not both",
                ))
            }
            Some(section) => {
                let (u, v) = self.initial_state(section, &model.mesh)?;
                // A frame at rest starts at rest (and may start a static analysis).
                (
                    u,
                    if v.iter().all(|&x| x == 0.0) {
                        Vec::new()
                    } else {
                        v
                    },
                )
            }
        };
        model.initial_displacement = initial_displacement;
        if !initial_velocity.is_empty() {
            if settings.analysis == Analysis::Static {
                return Err(self.invalid(
                    "body",
                    "an initial velocity (a body's `velocity` or `angular_velocity`, or `[initial]`) needs time.analysis = \"dynamic\"",
                ));
            }
            model.initial_velocity = initial_velocity;
        }
        let gravity_amplitude =
            self.amplitude("physics.gravity_amplitude", &raw.physics.gravity_amplitude)?;
        if !gravity_amplitude.is_one() {
            model.set_gravity(gravity, gravity_amplitude);
        }
        if let Some(contact) = contact {
            model.add_obstacles(contact);
        }
        if let Some(f) = &raw.freezing {
            if !raw.materials.is_empty() {
                return Err(self.invalid(
                    "freezing",
                    "freezing turns the `[material]` water to ice; it is not defined for scenes with [materials.NAME] entries (remove one or the other)",
                ));
            }
            let obstacles = model
                .obstacle_contact()
                .map_or(&[][..], |c| &c.obstacles[..]);
            let freezing = self.freezing(
                f,
                &model.mesh,
                &model.elasticity.eigenstrain,
                (&material, obstacles),
            )?;
            model.freezing = Some(freezing);
        }
        if let Some(p) = &raw.plasticity {
            let elastic_limit = self.positive("plasticity.elastic_limit", p.elastic_limit)?;
            let cap = p
                .max_plastic_strain
                .map(|c| self.positive("plasticity.max_plastic_strain", c))
                .transpose()?;
            model.elasticity.plasticity = Some(Plasticity { elastic_limit, cap });
        }
        let fracture = raw
            .fracture
            .as_ref()
            .map(|f| self.fracture(f, &model.mesh))
            .transpose()?;
        // Separate parts touch each other: ice–ice contact.
        let ice_friction = self.non_negative(
            "physics.ice_friction",
            raw.physics.ice_friction.unwrap_or(0.0),
        )?;
        let ice_stiffness = self.penalty(
            "physics.ice_stiffness",
            raw.physics.ice_stiffness,
            &model.mesh,
            &material,
        )?;
        model.set_ice_contact(IceContactTerm::new(
            &model.mesh,
            ice_stiffness,
            ice_friction,
            smoothing,
            &[],
            material.young(),
        ));
        let output = match &raw.output.file {
            Some(f) => PathBuf::from(f),
            None => PathBuf::from(self.path.file_stem().unwrap_or_default()).with_extension("h5"),
        };
        Ok(Scene {
            path: self.path.into(),
            text: text.into(),
            model,
            settings,
            end_time,
            output_every,
            output,
            fracture,
            notices: self.notices.take(),
        })
    }

    /// The elements `region` selects (at least one, else an error naming `field`).
    fn selected_elements(
        &self,
        field: &str,
        mesh: &TetMesh,
        region: &Selection,
    ) -> Result<Vec<usize>, SceneError> {
        let selected: Vec<usize> = (0..mesh.num_tets())
            .filter(|&t| region.contains_element(&mesh.tets[t].map(|v| mesh.rest[v])))
            .collect();
        if selected.is_empty() {
            return Err(self.invalid(
                field,
                format!(
                    "the {} contains no element centroid of the mesh",
                    region.describe()
                ),
            ));
        }
        Ok(selected)
    }

    fn fracture(
        &self,
        f: &FractureSection,
        mesh: &TetMesh,
    ) -> Result<FractureSettings, SceneError> {
        let in_range = |field: &str, v: f64, hi: f64| {
            if v.is_finite() && (0.0..hi).contains(&v) {
                Ok(v)
            } else {
                Err(self.invalid(field, format!("must be in [0, {hi}), got {v}")))
            }
        };
        let max_events_per_step = f.max_events_per_step.unwrap_or(8);
        if max_events_per_step == 0 {
            return Err(self.invalid(
                "fracture.max_events_per_step",
                "must be ≥ 1 (remove [fracture] to turn fracture off)",
            ));
        }
        let (lo, hi) = mesh.bounding_box();
        Ok(FractureSettings {
            toughness: self.positive("fracture.toughness", f.toughness)?,
            max_events_per_step,
            snap: in_range("fracture.snap", f.snap.unwrap_or(0.2), 0.5)?,
            min_quality: in_range("fracture.min_quality", f.min_quality.unwrap_or(0.1), 1.0)?,
            render_gap: match f.render_gap {
                Some(g) => self.non_negative("fracture.render_gap", g)?,
                None => 1e-3 * (hi - lo).norm(),
            },
            nonlocal_length: self
                .non_negative("fracture.nonlocal_length", f.nonlocal_length.unwrap_or(0.0))?,
        })
    }

    fn mesh(&self, m: &MeshSection) -> Result<TetMesh, SceneError> {
        let mesh_err = |source| SceneError::Mesh {
            path: self.path.into(),
            source,
        };
        let boxes: Vec<&BoxSection> = match (&m.box_, &m.boxes) {
            (Some(b), None) => vec![b],
            (None, Some(list)) if !list.is_empty() => list.iter().collect(),
            (None, Some(_)) => return Err(self.invalid("mesh.boxes", "must list at least one box")),
            (Some(_), Some(_)) => {
                return Err(self.invalid("mesh", "give `box` or `boxes`, not both"))
            }
            (None, None) => Vec::new(),
        };
        match (boxes.is_empty(), &m.file) {
            (false, None) => {
                if m.scale.is_some() {
                    return Err(self.invalid("mesh.scale", "applies to mesh files only"));
                }
                let field = |k: usize| {
                    if m.boxes.is_some() {
                        format!("mesh.boxes[{k}]")
                    } else {
                        "mesh.box".into()
                    }
                };
                self.check_boxes(&boxes, field)?;
                let mut parts = Vec::with_capacity(boxes.len());
                for b in &boxes {
                    let tpc = b.tets_per_cell.unwrap_or(6);
                    parts.push(box_mesh(b.origin, b.size, b.cells, tpc).map_err(mesh_err)?);
                }
                TetMesh::concat(parts).map_err(mesh_err)
            }
            (true, Some(file)) => {
                let scale = self.positive("mesh.scale", m.scale.unwrap_or(1.0))?;
                let (mesh, groups) = self.gmsh_file("mesh.file", file, scale)?;
                self.check_parts_apart("mesh.file", &mesh)?;
                self.add_groups("mesh.file", bodies::geometric_groups(&mesh, &groups))?;
                Ok(mesh)
            }
            _ => Err(self.invalid(
                "mesh",
                "give exactly one of `box`/`boxes` (built-in generator) or `file` (Gmsh .msh)",
            )),
        }
    }

    fn material(&self, m: &MaterialSection) -> Result<(Material, ElasticModel), SceneError> {
        let only_named = [
            ("region", m.region.is_some()),
            ("min", m.min.is_some()),
            ("max", m.max.is_some()),
        ];
        if let Some((key, _)) = only_named.iter().find(|(_, given)| *given) {
            return Err(self.invalid(
                &format!("material.{key}"),
                "[material] holds every element no other claims; regions belong to [materials.NAME] entries",
            ));
        }
        let material = self.constants(
            "material",
            m.density,
            [m.lambda, m.mu, m.youngs_modulus, m.poisson_ratio],
        )?;
        Ok((material, m.model.unwrap_or(ElasticModel::Corotated)))
    }

    /// A material from its density and `[lambda, mu, youngs_modulus, poisson_ratio]` (one
    /// pair given), the fields named under `field`.
    fn constants(
        &self,
        field: &str,
        density: f64,
        pairs: [Option<f64>; 4],
    ) -> Result<Material, SceneError> {
        let f = |name: &str| format!("{field}.{name}");
        let density = self.positive(&f("density"), density)?;
        Ok(match pairs {
            [Some(lambda), Some(mu), None, None] => {
                let lambda = self.finite(&f("lambda"), lambda)?;
                let mu = self.positive(&f("mu"), mu)?;
                // Positive bulk modulus ⇔ ν in (−1, 0.5); ν < 0.5 strictly (no incompressibility).
                if lambda + 2.0 * mu / 3.0 <= 0.0 {
                    return Err(self.invalid(&f("lambda"), format!("must be > −2μ/3 = {:e} Pa (positive bulk modulus), got {lambda:e}", -2.0 * mu / 3.0)));
                }
                Material { lambda, mu, density }
            }
            [None, None, Some(e), Some(nu)] => {
                let e = self.positive(&f("youngs_modulus"), e)?;
                if !(nu.is_finite() && nu > -1.0 && nu < 0.5) {
                    return Err(self.invalid(&f("poisson_ratio"), format!("must be in (−1, 0.5), got {nu}")));
                }
                Material::from_young_poisson(e, nu, density)
            }
            _ => {
                return Err(self.invalid(
                    field,
                    "give either `lambda` and `mu`, or `youngs_modulus` and `poisson_ratio` (exactly one pair)",
                ))
            }
        })
    }

    /// The `[materials.NAME]` entries into `elasticity`: bodies that name one are made of
    /// it, then the elements of each entry's region (overriding bodies').
    fn other_materials(
        &self,
        raw: &SceneFile,
        mesh: &TetMesh,
        bodies: &[std::ops::Range<usize>],
        elasticity: &mut Elasticity,
    ) -> Result<(), SceneError> {
        let names: Vec<&String> = raw.materials.keys().collect();
        if names.len() >= u16::MAX as usize {
            return Err(self.invalid("materials", format!("at most {} entries", u16::MAX - 1)));
        }
        let mut index = vec![0u16; mesh.num_tets()];
        let mut used = vec![false; names.len()];
        for (b, body) in raw.body.iter().enumerate() {
            let Some(name) = &body.material else { continue };
            let k = names.iter().position(|n| *n == name).ok_or_else(|| {
                self.invalid(
                    &format!("body[{b}].material"),
                    format!(
                        "no [materials.{name}] entry (the scene's materials: {})",
                        if names.is_empty() {
                            "none".to_string()
                        } else {
                            names
                                .iter()
                                .map(|n| format!("{n:?}"))
                                .collect::<Vec<_>>()
                                .join(", ")
                        }
                    ),
                )
            })?;
            index[bodies[b].clone()].fill(k as u16 + 1);
            used[k] = true;
        }
        for (k, (name, m)) in raw.materials.iter().enumerate() {
            let field = format!("materials.{name}");
            if m.model.is_some() || m.volumetric.is_some() {
                let key = if m.model.is_some() {
                    "model"
                } else {
                    "volumetric"
                };
                return Err(self.invalid(
                    &format!("{field}.{key}"),
                    "is set for all materials by [material]",
                ));
            }
            let material = self.constants(
                &field,
                m.density,
                [m.lambda, m.mu, m.youngs_modulus, m.poisson_ratio],
            )?;
            elasticity.other_materials.push(material);
            if m.min.is_none() && m.max.is_none() && m.region.is_none() {
                if !used[k] {
                    return Err(self.invalid(
                        &field,
                        "is used nowhere: give it a `region` (or `min`/`max`), or name it in a [[body]]'s `material`",
                    ));
                }
                continue;
            }
            let region = self.selection(&field, (m.min, m.max, m.region.as_ref()), Some(3))?;
            for t in self.selected_elements(&field, mesh, &region)? {
                index[t] = k as u16 + 1;
            }
        }
        if index.iter().any(|&k| k > 0) {
            elasticity.material_index = index;
        }
        Ok(())
    }

    fn obstacle(
        &self,
        i: usize,
        o: &ObstacleSection,
        mesh: &TetMesh,
        material: &Material,
    ) -> Result<Obstacle, SceneError> {
        let field = format!("obstacle[{i}]");
        let f = |name: &str| format!("{field}.{name}");
        let misplaced = [
            ("point", o.point.is_some(), "halfspace"),
            ("normal", o.normal.is_some(), "halfspace"),
            ("min", o.min.is_some(), "container"),
            ("max", o.max.is_some(), "container"),
            ("file", o.file.is_some(), "mesh"),
            ("scale", o.scale.is_some(), "mesh"),
            ("translate", o.translate.is_some(), "mesh"),
        ];
        if let Some((name, _, owner)) = misplaced
            .iter()
            .find(|(_, given, owner)| *given && *owner != o.kind)
        {
            return Err(self.invalid(
                &f(name),
                format!(
                    "belongs to type = \"{owner}\" obstacles, not \"{}\"",
                    o.kind
                ),
            ));
        }
        let shape = match o.kind.as_str() {
            "halfspace" => {
                let point = o.point.ok_or_else(|| {
                    self.invalid(&f("point"), "missing (a point on the surface, m)")
                })?;
                let normal = o
                    .normal
                    .ok_or_else(|| self.invalid(&f("normal"), "missing (outward normal)"))?;
                let normal = self.vector(&f("normal"), normal)?;
                if normal.norm() == 0.0 {
                    return Err(self.invalid(&f("normal"), "must not be zero"));
                }
                Shape::HalfSpace {
                    point: self.vector(&f("point"), point)?,
                    normal: normal.normalize(),
                }
            }
            "container" => {
                let min = o
                    .min
                    .ok_or_else(|| self.invalid(&f("min"), "missing (inner lower corner, m)"))?;
                let max = o
                    .max
                    .ok_or_else(|| self.invalid(&f("max"), "missing (inner upper corner, m)"))?;
                let inner = self.region(&field, min, max)?;
                if (0..3).any(|a| inner.max[a] <= inner.min[a]) {
                    return Err(self.invalid(&f("max"), "must exceed `min` on every axis"));
                }
                Shape::Container { inner }
            }
            "mesh" => {
                let file = o.file.as_ref().ok_or_else(|| {
                    self.invalid(&f("file"), "missing (surface mesh, .obj or .msh)")
                })?;
                let scale = self.positive(&f("scale"), o.scale.unwrap_or(1.0))?;
                let shift = self.vector(&f("translate"), o.translate.unwrap_or_default())?;
                let file = self.path.parent().unwrap_or(Path::new("")).join(file);
                let mut surface =
                    TriSurface::read(&file, scale).map_err(|source| SceneError::SurfaceFile {
                        path: self.path.into(),
                        field: f("file"),
                        source,
                    })?;
                for v in &mut surface.vertices {
                    *v += shift;
                }
                if surface.is_closed() && surface.enclosed_volume() < 0.0 {
                    return Err(self.invalid(
                        &f("file"),
                        format!("{}: the surface is closed but its triangles face inward (negative enclosed volume {:e} m³); reverse their order so normals point out of the obstacle", file.display(), surface.enclosed_volume()),
                    ));
                }
                Shape::Mesh {
                    surface: Arc::new(ObstacleSurface::new(&surface)),
                }
            }
            other => {
                return Err(self.invalid(
                    &f("type"),
                    format!("must be \"halfspace\", \"container\" or \"mesh\", got {other:?}"),
                ))
            }
        };
        let stiffness = self.penalty(&f("stiffness"), o.stiffness, mesh, material)?;
        if o.centre.is_some() && o.angular_velocity.is_none() {
            return Err(self.invalid(
                &f("centre"),
                "is the point the obstacle turns about: give `angular_velocity` with it",
            ));
        }
        if o.amplitude.is_some() && o.velocity.is_none() && o.angular_velocity.is_none() {
            return Err(self.invalid(
                &f("amplitude"),
                "scales the obstacle's `velocity` and `angular_velocity`: give one of them",
            ));
        }
        Ok(Obstacle {
            shape,
            motion: Motion {
                velocity: self.vector(&f("velocity"), o.velocity.unwrap_or_default())?,
                angular_velocity: self.vector(
                    &f("angular_velocity"),
                    o.angular_velocity.unwrap_or_default(),
                )?,
                centre: self.vector(&f("centre"), o.centre.unwrap_or_default())?,
                amplitude: self.amplitude(&f("amplitude"), &o.amplitude)?,
            },
            stiffness,
            friction: self.non_negative(&f("friction"), o.friction.unwrap_or(0.0))?,
        })
    }

    fn dirichlet(&self, i: usize, d: &DirichletSection) -> Result<Dirichlet, SceneError> {
        let field = format!("dirichlet[{i}]");
        let region = self.selection(&field, (d.min, d.max, d.region.as_ref()), None)?;
        let axes_text = d.axes.as_deref().unwrap_or("xyz");
        let mut axes = [false; 3];
        for c in axes_text.chars() {
            match c {
                'x' => axes[0] = true,
                'y' => axes[1] = true,
                'z' => axes[2] = true,
                _ => {
                    return Err(self.invalid(
                        &format!("{field}.axes"),
                        format!("must be letters from \"xyz\", got {axes_text:?}"),
                    ))
                }
            }
        }
        if axes_text.is_empty() {
            return Err(self.invalid(&format!("{field}.axes"), "must name at least one axis"));
        }
        Ok(Dirichlet {
            region,
            axes,
            amplitude: self.amplitude(&format!("{field}.amplitude"), &d.amplitude)?,
            displacement: self.vector(
                &format!("{field}.displacement"),
                d.displacement.unwrap_or_default(),
            )?,
            velocity: self.vector(&format!("{field}.velocity"), d.velocity.unwrap_or_default())?,
        })
    }
}

/// "surface" or "volume" for a group of dimension 2 or 3.
fn kind_name(dim: u8) -> &'static str {
    if dim == 3 {
        "volume"
    } else {
        "surface"
    }
}
