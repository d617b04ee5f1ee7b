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
use crate::mesh::{gmsh, MeshError, TetMesh};
use crate::output::FrameOptions;
use crate::physics::freezing::Freezing;
use crate::physics::ice_contact::IceContactTerm;
use crate::physics::plasticity::Plasticity;
use crate::physics::term::NodeRestriction;
use crate::physics::{Amplitude, Dirichlet, Elasticity, Group, Model, Rayleigh, Region, Traction};
use crate::sim::part::Part;
use crate::sim::{Analysis, StepSettings};
use crate::solver::{FactorPrecision, FillOrdering, LinearSolverKind};
use nalgebra::Vector3;
use regions::SelectionKeys;
use serde::Deserialize;
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::sync::Arc;

mod bodies;
mod checks;
mod creep;
mod freezing;
mod materials;
mod obstacles;
mod output;
mod regions;
mod shared;
mod stepping;
mod thermal;

pub use bodies::{BodySection, InitialSection, RotateSection};
pub use freezing::FreezingSection;
pub use materials::MaterialSection;
pub use obstacles::ObstacleSection;
pub use output::{DrawnPrecision, OutputSection};
pub use shared::{builds_on_parts, MeshRanges, MeshSharing, SharedMesh};
pub use thermal::{HeatSetup, ThermalSection};

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
    /// Heat conduction driving the freezing (instead of `[freezing]`'s prescribed front).
    pub thermal: Option<ThermalSection>,
    /// Plasticity (off if absent).
    pub plasticity: Option<PlasticitySection>,
    /// Creep (off if absent).
    pub creep: Option<creep::CreepSection>,
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
    /// "backward_euler" (default) or "newmark" (dynamic analyses).
    pub scheme: Option<crate::sim::Scheme>,
    /// Time step (s).
    pub dt: f64,
    /// End time (s).
    pub end_time: f64,
    /// Write a frame every this many steps (of `dt`). Default 1.
    pub output_every: Option<u64>,
    /// Steps between restart points (fixed steps): the solver starts them with a fresh
    /// factorisation, whatever the frames, and a frame written there is where `--resume`
    /// continues from. Default 10.
    pub restart_every: Option<u64>,
    /// Adaptive steps (dynamic analyses).
    pub adaptive: Option<AdaptiveSection>,
}

/// `[time.adaptive]`: steps chosen by their local error estimate; `dt` is the first step, and
/// frames are still written every `output_every × dt` of simulated time.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AdaptiveSection {
    /// Local error allowed per step relative to the largest displacement; default 1e-3.
    pub relative_tolerance: Option<f64>,
    /// Local error allowed per step when nothing has moved (m); default the relative
    /// tolerance × 1e-6 × the mesh's bounding-box diagonal (the displacement of a strain of
    /// 1e-6 across the body: ice under its own weight and loads strains 1e-8 … 1e-3).
    pub absolute_tolerance: Option<f64>,
    /// Shortest step (s); default dt / 1000.
    pub dt_min: Option<f64>,
    /// Longest step (s); default the frame interval, `output_every × dt`.
    pub dt_max: Option<f64>,
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

/// A validated scene.
#[derive(Clone, Debug)]
pub struct Scene {
    /// Where it was read from.
    pub path: PathBuf,
    /// The scene text (stored in the output).
    pub text: String,
    /// The mechanics. Its elements are described (materials, eigenstrains, discretisation)
    /// without their rest data, which the simulation builds on the mesh it runs: a run on
    /// several processes builds it for each process's part only.
    pub model: Model,
    /// Stepping and solver settings.
    pub settings: StepSettings,
    /// End time (s).
    pub end_time: f64,
    /// Steps per output frame.
    pub output_every: u64,
    /// Steps between restart points (`[time] restart_every`; fixed steps only: with adaptive
    /// steps every frame on the output grid is one).
    pub restart_every: u64,
    /// Default output file.
    pub output: PathBuf,
    /// What frames store besides a resumed run's state (`[output]`).
    pub frame_options: FrameOptions,
    /// The heat model driving the freezing (`[thermal]`).
    pub thermal: Option<HeatSetup>,
    /// Fracture, if on.
    pub fracture: Option<FractureSettings>,
    /// The process's part of the mesh `model` is built on, where the scene was built on parts
    /// (a run shared among processes, see [`MeshSharing`]); none: on the whole mesh. A
    /// part's model has its masses and dead loads at the nodes the process owns only.
    pub part: Option<Part>,
    /// What the user should know about the input that is not an error (one line each), such
    /// as mesh elements that were reoriented.
    pub notices: Vec<String>,
    /// What looks like a mistake in the input but is not certainly one (one line each), such
    /// as a body a thousand times larger than its container: repeated after the run.
    pub warnings: Vec<String>,
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
        Scene::parse_shared(text, path, None)
    }

    /// As [`Scene::load`], built on this process's part of the mesh where the processes
    /// `sharing` are given and the scene [`builds_on_parts`]. Every process calls it.
    pub fn load_shared(
        path: &Path,
        sharing: Option<&dyn MeshSharing>,
    ) -> Result<Scene, SceneError> {
        let text = std::fs::read_to_string(path).map_err(|source| SceneError::Io {
            path: path.into(),
            source,
        })?;
        Scene::parse_shared(&text, path, sharing)
    }

    /// As [`Scene::parse`], built on this process's part of the mesh as [`Scene::load_shared`].
    pub fn parse_shared(
        text: &str,
        path: &Path,
        sharing: Option<&dyn MeshSharing>,
    ) -> Result<Scene, SceneError> {
        let raw: SceneFile = toml::from_str(text).map_err(|e| SceneError::Parse {
            path: path.into(),
            message: e.to_string(),
        })?;
        let whole = shared::needs_whole_mesh(&raw);
        let validator = Validator {
            path,
            notices: Default::default(),
            warnings: Default::default(),
            groups: Default::default(),
            sharing: std::cell::Cell::new(sharing.filter(|_| whole.is_none())),
            part: Default::default(),
        };
        if let (Some(_), Some(section)) = (sharing, whole) {
            validator.whole_on_every_process(section);
        }
        validator.scene(raw, text)
    }

    /// Nodes and elements of the whole mesh.
    pub fn counts(&self) -> (usize, usize) {
        match &self.part {
            Some(part) => (part.whole_nodes(), part.whole_elements()),
            None => (self.model.mesh.num_nodes(), self.model.mesh.num_tets()),
        }
    }
}

struct Validator<'a> {
    path: &'a Path,
    /// What the user should know about the input that is not an error.
    notices: std::cell::RefCell<Vec<String>>,
    /// What looks like a mistake in the input (see [`Scene::warnings`]).
    warnings: std::cell::RefCell<Vec<String>>,
    /// The mesh files' named physical groups, placed as the scene places the mesh.
    groups: std::cell::RefCell<Vec<Arc<Group>>>,
    /// The processes that build the scene on their parts of the mesh, if it is built so.
    sharing: std::cell::Cell<Option<&'a dyn MeshSharing>>,
    /// This process's part of the mesh, and its elements' faces on the whole mesh's boundary,
    /// once shared out (see `shared`).
    part: std::cell::RefCell<Option<(Part, Vec<u8>)>>,
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

    /// The scene of `raw` (read from `text`), checked section by section in the order the
    /// model is built.
    fn scene(&self, raw: SceneFile, text: &str) -> Result<Scene, SceneError> {
        let bodies = self.mesh_or_bodies(&raw)?;
        let mesh = bodies.mesh;
        let (material, elastic_model) = self.material(&raw.material)?;
        let gravity = self.vector("physics.gravity", raw.physics.gravity.unwrap_or_default())?;
        let damping = self.damping(&raw.physics)?;
        let dirichlet = raw
            .dirichlet
            .iter()
            .enumerate()
            .map(|(i, d)| self.dirichlet(i, d))
            .collect::<Result<Vec<_>, _>>()?;
        let tractions = self.tractions(&raw.traction, &mesh)?;
        let stepping = self.stepping(&raw.time, &raw.solver, &mesh)?;
        let settings = stepping.settings;
        let elasticity = self.elasticity(&raw, &mesh, &bodies.elements, material, elastic_model)?;
        let obstacles = raw
            .obstacle
            .iter()
            .enumerate()
            .map(|(i, o)| self.obstacle(i, o, &mesh, &material))
            .collect::<Result<Vec<_>, _>>()?;
        self.check_outside_obstacles(&mesh, &obstacles)?;
        let scale_key = if raw.mesh.is_some() {
            "[mesh] scale"
        } else {
            "[[body]] scale"
        };
        self.check_sizes(&mesh, &obstacles, scale_key);
        let smoothing = self.positive(
            "physics.friction_smoothing_velocity",
            raw.physics.friction_smoothing_velocity.unwrap_or(1e-4),
        )?;
        let contact = (!obstacles.is_empty()).then(|| self.contact(&mesh, obstacles, smoothing));
        let mut model = Model::new(mesh, elasticity, gravity, &tractions, damping, dirichlet)
            .map_err(|source| SceneError::Mesh {
                path: self.path.into(),
                source,
            })?;
        self.set_initial_state(&raw, &mut model, bodies.velocity, settings.analysis)?;
        let gravity_amplitude =
            self.amplitude("physics.gravity_amplitude", &raw.physics.gravity_amplitude)?;
        if !gravity_amplitude.is_one() {
            model.set_gravity(gravity, gravity_amplitude);
        }
        if let Some(contact) = contact {
            model.add_obstacles(contact);
        }
        let thermal = raw
            .thermal
            .as_ref()
            .map(|t| self.thermal(t, (&model.mesh, &model.mass)))
            .transpose()?;
        if let Some(mut freezing) =
            self.model_freezing(&raw, thermal.as_ref(), &model, &material)?
        {
            let section = raw.freezing.as_ref();
            freezing.displaces_water =
                section.map(|f| self.displaces_water(f)).transpose()? == Some(true);
            model.elasticity.ice_formation = freezing.displaces_water;
            model.freezing = Some(freezing);
        }
        if let Some(p) = &raw.plasticity {
            model.elasticity.plasticity = Some(self.plasticity(p)?);
        }
        if let Some(c) = &raw.creep {
            if raw.plasticity.is_some() {
                return Err(self.invalid(
                    "creep",
                    "[creep] and [plasticity] are two flow rules for the same strain; a scene takes one (remove one section)",
                ));
            }
            model.elasticity.creep = Some(self.creep(c, raw.thermal.is_some())?);
        }
        let fracture = raw
            .fracture
            .as_ref()
            .map(|f| self.fracture(f, &model.mesh))
            .transpose()?;
        self.check_scheme(&settings, fracture.is_some())?;
        let ice_contact = self.ice_contact(
            &raw.physics,
            (&model.mesh, &material),
            smoothing,
            fracture.is_some(),
        )?;
        model.set_ice_contact(ice_contact);
        let part = self.part.take().map(|(part, _)| part);
        if let Some(part) = &part {
            // Masses, dead loads and terms at the owned nodes only, whose elements are all
            // the part's.
            let terms = std::mem::take(&mut model.terms);
            model.restrict(
                &part.owned_nodes,
                &terms,
                &NodeRestriction::all(&part.owned_nodes),
            );
        }
        let output = match &raw.output.file {
            Some(f) => PathBuf::from(f),
            None => PathBuf::from(self.path.file_stem().unwrap_or_default()).with_extension("h5"),
        };
        Ok(Scene {
            path: self.path.into(),
            text: text.into(),
            model,
            settings,
            end_time: stepping.end_time,
            output_every: stepping.output_every,
            restart_every: stepping.restart_every,
            output,
            frame_options: output::frame_options(&raw.output, stepping.output_every),
            fracture,
            thermal,
            part,
            notices: self.notices.take(),
            warnings: self.warnings.take(),
        })
    }

    /// Rayleigh damping of `[physics.damping]`, if given.
    fn damping(&self, physics: &PhysicsSection) -> Result<Option<Rayleigh>, SceneError> {
        match &physics.damping {
            Some(d) => Ok(Some(Rayleigh {
                mass: self.non_negative("physics.damping.mass", d.mass)?,
                stiffness: self.non_negative("physics.damping.stiffness", d.stiffness)?,
            })),
            None => Ok(None),
        }
    }

    /// The `[[traction]]` entries, each on at least one boundary face of `mesh`.
    fn tractions(
        &self,
        sections: &[TractionSection],
        mesh: &TetMesh,
    ) -> Result<Vec<Traction>, SceneError> {
        let mut tractions = Vec::new();
        for (i, t) in sections.iter().enumerate() {
            let field = format!("traction[{i}]");
            let keys = SelectionKeys {
                min: t.min,
                max: t.max,
                region: t.region.as_ref(),
            };
            let region = self.selection(&field, keys, Some(2))?;
            let traction = Traction {
                region: region.clone(),
                traction: self.vector(&format!("{field}.traction"), t.traction)?,
                amplitude: self.amplitude(&format!("{field}.amplitude"), &t.amplitude)?,
            };
            let faces = self.whole_boundary(mesh);
            let found = crate::physics::loads::traction_faces_among(mesh, &faces, &region).0;
            if self.found_anywhere(found) == 0 {
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
        Ok(tractions)
    }

    /// The elasticity of `mesh`: `[material]` of strain measure `model`, the
    /// `[materials.NAME]` of the bodies (`bodies`: each one's elements) and regions, the
    /// volumetric discretisation and the `[[eigenstrain]]` entries.
    fn elasticity(
        &self,
        raw: &SceneFile,
        mesh: &TetMesh,
        bodies: &[Range<usize>],
        material: Material,
        model: ElasticModel,
    ) -> Result<Elasticity, SceneError> {
        let mut elasticity = Elasticity::described(mesh, material, model);
        self.other_materials(raw, mesh, bodies, &mut elasticity)?;
        elasticity.set_volumetric(mesh, raw.material.volumetric.unwrap_or_default());
        for (i, section) in raw.eigenstrain.iter().enumerate() {
            let field = format!("eigenstrain[{i}]");
            let keys = SelectionKeys {
                min: section.min,
                max: section.max,
                region: section.region.as_ref(),
            };
            let region = self.selection(&field, keys, Some(3))?;
            let e = section.value;
            // Physical eigenstrains are a few percent; beyond ±0.5 the small-strain reading of
            // σ = C:(ε − e I) and the multiplicative corotated form part ways.
            if !(e.is_finite() && e.abs() < 0.5) {
                return Err(self.invalid(
                    &format!("{field}.value"),
                    format!("must be in (−0.5, 0.5), got {e}"),
                ));
            }
            for t in self.selected_elements(&field, mesh, &region)? {
                elasticity.eigenstrain[t] = e;
            }
        }
        Ok(elasticity)
    }

    /// The initial displacement of `[initial]` and the initial velocity of `[initial]` or of
    /// the bodies (`body_velocity`, empty: at rest) into `model`; a velocity needs a dynamic
    /// `analysis`.
    fn set_initial_state(
        &self,
        raw: &SceneFile,
        model: &mut Model,
        body_velocity: Vec<f64>,
        analysis: Analysis,
    ) -> Result<(), SceneError> {
        let (initial_displacement, initial_velocity) = match &raw.initial {
            None => (Vec::new(), body_velocity),
            Some(_) if !body_velocity.is_empty() => {
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
            if analysis == Analysis::Static {
                return Err(self.invalid(
                    "body",
                    "an initial velocity (a body's `velocity` or `angular_velocity`, or `[initial]`) needs time.analysis = \"dynamic\"",
                ));
            }
            model.initial_velocity = initial_velocity;
        }
        Ok(())
    }

    /// The freezing of `model`'s `[material]` water (of ice `ice`): driven by the heat model
    /// `thermal`, or by `[freezing]`'s prescribed front; none without either.
    fn model_freezing(
        &self,
        raw: &SceneFile,
        thermal: Option<&HeatSetup>,
        model: &Model,
        ice: &Material,
    ) -> Result<Option<Freezing>, SceneError> {
        if thermal.is_none() && raw.material.thermal_expansion.is_some() {
            return Err(self.invalid(
                "material.thermal_expansion",
                "thermal strain needs temperatures: add a [thermal] section (or remove the key)",
            ));
        }
        if let Some(setup) = thermal {
            if !raw.materials.is_empty() {
                return Err(self.invalid(
                    "thermal",
                    "[thermal] freezes the `[material]` water; it is not defined for scenes with [materials.NAME] entries",
                ));
            }
            let expansion = raw
                .material
                .thermal_expansion
                .as_ref()
                .map(|key| self.thermal_expansion(key))
                .transpose()?;
            Ok(Some(self.thermal_freezing(
                raw.freezing.as_ref(),
                setup,
                (&model.mesh, &model.elasticity.eigenstrain),
                ice,
                expansion,
            )?))
        } else if let Some(f) = &raw.freezing {
            if !raw.materials.is_empty() {
                return Err(self.invalid(
                    "freezing",
                    "freezing turns the `[material]` water to ice; it is not defined for scenes with [materials.NAME] entries (remove one or the other)",
                ));
            }
            Ok(Some(self.freezing(f, model, ice)?))
        } else {
            Ok(None)
        }
    }

    /// The plasticity of `[plasticity]`.
    fn plasticity(&self, p: &PlasticitySection) -> Result<Plasticity, SceneError> {
        let elastic_limit = self.positive("plasticity.elastic_limit", p.elastic_limit)?;
        let cap = p
            .max_plastic_strain
            .map(|c| self.positive("plasticity.max_plastic_strain", c))
            .transpose()?;
        Ok(Plasticity { elastic_limit, cap })
    }

    /// Ice–ice contact between the separate parts of `mesh` (of `material`), or across the
    /// cracks if the scene has `fracture`, friction smoothed over `smoothing` (m/s) as with the
    /// obstacles.
    fn ice_contact(
        &self,
        physics: &PhysicsSection,
        (mesh, material): (&TetMesh, &Material),
        smoothing: f64,
        fracture: bool,
    ) -> Result<IceContactTerm, SceneError> {
        let ice_friction =
            self.non_negative("physics.ice_friction", physics.ice_friction.unwrap_or(0.0))?;
        // The default stiffness (a pass over the whole boundary) only for a term that can
        // come on: one part without fracture never has a pair.
        // A scene built on parts is one connected part (see `shared::builds_on_parts`).
        let one_part = self.sharing.get().is_some() || crate::mesh::parts(mesh).1 < 2;
        if physics.ice_stiffness.is_none() && !fracture && one_part {
            return Ok(IceContactTerm::inactive(0.0, ice_friction, smoothing));
        }
        let ice_stiffness = self.penalty(
            "physics.ice_stiffness",
            physics.ice_stiffness,
            mesh,
            material,
        )?;
        if self.sharing.get().is_some() {
            // One connected part (a process's part of it may have several pieces, which
            // touch through the elements of others): the term comes on at the first crack,
            // where the processes' fracture builds it (`distributed::rebuild`).
            return Ok(IceContactTerm::inactive(
                ice_stiffness,
                ice_friction,
                smoothing,
            ));
        }
        Ok(IceContactTerm::new(
            mesh,
            ice_stiffness,
            ice_friction,
            smoothing,
            &[],
            material.young(),
        ))
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
        let (lo, hi) = self.bounding_box(mesh);
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

    fn dirichlet(&self, i: usize, d: &DirichletSection) -> Result<Dirichlet, SceneError> {
        let field = format!("dirichlet[{i}]");
        let keys = SelectionKeys {
            min: d.min,
            max: d.max,
            region: d.region.as_ref(),
        };
        let region = self.selection(&field, keys, None)?;
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
