//! The physical model of a scene: elasticity, mass, loads, damping, boundary conditions and
//! the terms the scene enables (see [`term`]); a term that is off costs nothing. The model is
//! fixed between remeshes: what depends on time (the dead loads of a time-varying amplitude,
//! the freeze states) it gives at a time, and what changes from step to step is in the
//! simulation's state ([`history`]) and step data.

pub mod amplitude;
pub mod contact;
pub mod contact_forces;
pub mod crack_sides;
pub mod creep;
pub mod dirichlet;
pub mod distance;
pub mod elasticity;
pub mod freezing;
pub mod grid;
pub mod history;
pub mod ice_contact;
pub mod ice_formation;
pub mod inertia;
pub mod loads;
pub mod motion;
pub mod obstacle_mesh;
pub mod plasticity;
pub mod selection;
pub mod term;
pub mod thermal_strain;
pub mod volumetric;

pub use amplitude::Amplitude;
pub use contact::{Contact, Obstacle};
pub use dirichlet::Dirichlet;
pub use elasticity::Elasticity;
pub use loads::Traction;
pub use motion::Motion;
pub use selection::{Group, Selection};

use crate::mesh::{MeshError, TetMesh};
use history::ElementHistory;
use ice_contact::{IceContact, IceContactTerm};
use nalgebra::Vector3;
use term::{NodeRestriction, Remesh, Term, TermHistory, WholeMesh};

/// Axis-aligned box region in rest coordinates (m), bounds inclusive.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Region {
    /// Lower corner (m).
    pub min: Vector3<f64>,
    /// Upper corner (m).
    pub max: Vector3<f64>,
}

impl Region {
    /// Whether `p` lies in the box (inclusive).
    pub fn contains(&self, p: &Vector3<f64>) -> bool {
        (0..3).all(|a| p[a] >= self.min[a] && p[a] <= self.max[a])
    }
}

/// Rayleigh damping D = α M + β K (K evaluated at the start of each step).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Rayleigh {
    /// Mass-proportional coefficient α (1/s).
    pub mass: f64,
    /// Stiffness-proportional coefficient β (s).
    pub stiffness: f64,
}

/// Everything that defines the mechanics of a run, independent of its time-dependent state.
#[derive(Clone, Debug)]
pub struct Model {
    /// The mesh in its rest configuration.
    pub mesh: TetMesh,
    /// Elastic energy of the elements.
    pub elasticity: Elasticity,
    /// Lumped nodal mass (kg), one per node.
    pub mass: Vec<f64>,
    /// The dead loads whose amplitude is 1 throughout (N, 3 per node).
    constant_force: Vec<f64>,
    /// The dead loads that vary in time: amplitude and nodal forces at amplitude 1 (N).
    varying_forces: Vec<(Amplitude, Vec<f64>)>,
    /// Rayleigh damping, if any.
    pub damping: Option<Rayleigh>,
    /// Dirichlet conditions.
    pub dirichlet: Vec<Dirichlet>,
    /// The terms the scene enables beyond elasticity, loads, inertia and damping, in the
    /// order their energies are summed: obstacle contact (if the scene has obstacles), then
    /// ice–ice contact (active when the mesh has several parts or cracks).
    pub terms: Vec<Box<dyn Term>>,
    /// Freezing schedule, if the scene freezes (none: every element is ice throughout).
    pub freezing: Option<freezing::Freezing>,
    /// Gravity (m/s²) at amplitude 1, kept to rebuild the loads after a topology change.
    pub gravity: Vector3<f64>,
    /// Amplitude of gravity in time.
    pub gravity_amplitude: Amplitude,
    /// Displacement of each node at t = 0 (m, 3 per node); empty: none.
    pub initial_displacement: Vec<f64>,
    /// Velocity of each node at t = 0 (m/s, 3 per node); empty: at rest.
    pub initial_velocity: Vec<f64>,
    /// Surface tractions, kept likewise.
    pub tractions: Vec<Traction>,
}

impl Model {
    /// Assembles the model: lumped mass ρV/4 per tet vertex, gravity m g on each node, the
    /// given tractions on boundary faces; ice–ice contact with the default stiffness, without
    /// friction, inactive until a remesh gives the mesh several parts or cracks.
    pub fn new(
        mesh: TetMesh,
        elasticity: Elasticity,
        gravity: Vector3<f64>,
        tractions: &[Traction],
        damping: Option<Rayleigh>,
        dirichlet: Vec<Dirichlet>,
    ) -> Result<Self, MeshError> {
        let mass = loads::lumped_mass(&mesh, |e| elasticity.base_material(e).density);
        let mut model = Model {
            mesh,
            elasticity,
            constant_force: Vec::new(),
            varying_forces: Vec::new(),
            mass,
            damping,
            dirichlet,
            terms: vec![Box::new(IceContactTerm::inactive(0.0, 0.0, 1e-4))],
            freezing: None,
            gravity,
            gravity_amplitude: Amplitude::default(),
            initial_displacement: Vec::new(),
            initial_velocity: Vec::new(),
            tractions: tractions.to_vec(),
        };
        model.build_loads();
        Ok(model)
    }

    /// Sets gravity (m/s², at amplitude 1) and its amplitude in time; the dead loads are then
    /// those at t = 0.
    pub fn set_gravity(&mut self, gravity: Vector3<f64>, amplitude: Amplitude) {
        self.gravity = gravity;
        self.gravity_amplitude = amplitude;
        self.build_loads();
    }

    /// Builds the nodal dead loads from gravity and the tractions: those of amplitude 1 summed
    /// once (gravity first), the others kept apart.
    fn build_loads(&mut self) {
        let n = 3 * self.mesh.num_nodes();
        let mut constant = vec![0.0; n];
        let mut varying = Vec::new();
        if self.gravity != Vector3::zeros() {
            if self.gravity_amplitude.is_one() {
                loads::add_gravity(&self.mass, &self.gravity, &mut constant);
            } else {
                let mut force = vec![0.0; n];
                loads::add_gravity(&self.mass, &self.gravity, &mut force);
                varying.push((self.gravity_amplitude.clone(), force));
            }
        }
        for t in &self.tractions {
            if t.amplitude.is_one() {
                loads::add_traction(&self.mesh, t, &mut constant);
            } else {
                let mut force = vec![0.0; n];
                loads::add_traction(&self.mesh, t, &mut force);
                varying.push((t.amplitude.clone(), force));
            }
        }
        self.constant_force = constant;
        self.varying_forces = varying;
    }

    /// Writes the dead loads (gravity and surface tractions) at time `t` (s) into `loads` (N,
    /// 3 per node); leaves `loads` as it is where they do not vary in time and it holds them.
    pub fn dead_loads_into(&self, t: f64, loads: &mut Vec<f64>) {
        if self.varying_forces.is_empty() && loads.len() == self.constant_force.len() {
            return;
        }
        loads.clone_from(&self.constant_force);
        for (amplitude, force) in &self.varying_forces {
            let a = amplitude.at(t);
            for (f, g) in loads.iter_mut().zip(force) {
                *f += a * g;
            }
        }
    }

    /// The dead loads at time `t` (s) on every dof (N, 3 per node).
    pub fn dead_loads_at(&self, t: f64) -> Vec<f64> {
        let mut loads = Vec::new();
        self.dead_loads_into(t, &mut loads);
        loads
    }

    /// The model on a new mesh made from this one by splitting elements (fracture): `parent[e]`
    /// is the element of this model that new element `e` came from, and inherits its
    /// prescribed eigenstrain and freezing schedule. Mass and loads are rebuilt from the new
    /// rest volumes and boundary (total mass is unchanged when the rest volume is), and every
    /// term rebuilds itself on the new mesh with the crack faces `cracks` (node triples; their
    /// two sides must not interpenetrate).
    pub fn remeshed(
        &self,
        rest: &[Vector3<f64>],
        tets: Vec<[usize; 4]>,
        parent: &[usize],
        cracks: &[[usize; 3]],
    ) -> Result<Model, MeshError> {
        let rows: Vec<[f64; 3]> = rest.iter().map(|x| [x.x, x.y, x.z]).collect();
        let mesh = TetMesh::from_arrays(&rows, tets)?;
        let boundary = mesh.boundary_faces();
        let perimeters = mesh.perimeters(&boundary);
        let (piece, pieces) = crate::mesh::parts(&mesh);
        let whole = WholeMesh {
            boundary: &boundary,
            perimeters: &perimeters,
            bounds: mesh.bounding_box(),
            pieces: (&piece, pieces),
        };
        self.remeshed_on(mesh, parent, cracks, &whole)
    }

    /// [`Model::remeshed`] on `mesh`, which is `whole` (a process's part of the split mesh,
    /// or all of it), with `cracks` its crack faces: what lives on its elements and at the
    /// nodes whose elements it all holds is the whole model's there.
    pub fn remeshed_on(
        &self,
        mesh: TetMesh,
        parent: &[usize],
        cracks: &[[usize; 3]],
        whole: &WholeMesh,
    ) -> Result<Model, MeshError> {
        let old = &self.elasticity;
        let elasticity = old.remeshed(&mesh, parent);
        let mut model = Model::new(
            mesh,
            elasticity,
            self.gravity,
            &self.tractions,
            self.damping,
            self.dirichlet.clone(),
        )?;
        if !self.gravity_amplitude.is_one() {
            model.set_gravity(self.gravity, self.gravity_amplitude.clone());
        }
        let remesh = Remesh {
            mesh: &model.mesh,
            parent,
            cracks,
            young: old.material.young(),
            whole,
        };
        model.terms = self.terms.iter().map(|t| t.remeshed(&remesh)).collect();
        model.freezing = self.freezing.as_ref().map(|f| f.inherit(parent));
        Ok(model)
    }

    /// Makes this model a process's share of a distributed run: masses and dead loads only
    /// on the nodes the process owns (`owned`, one per node of this model's mesh), zero on
    /// the others, and `terms` (the whole model's) restricted to them by `part`. Each owned
    /// node's elements must all be in this model's mesh, so that its mass and loads are whole.
    pub fn restrict(&mut self, owned: &[bool], terms: &[Box<dyn Term>], part: &NodeRestriction) {
        for (i, _) in owned.iter().enumerate().filter(|(_, &o)| !o) {
            self.mass[i] = 0.0;
            let forces = std::iter::once(&mut self.constant_force)
                .chain(self.varying_forces.iter_mut().map(|(_, f)| f));
            for f in forces {
                f[3 * i..3 * i + 3].fill(0.0);
            }
        }
        self.terms = terms.iter().map(|t| t.restricted(part)).collect();
    }

    /// What this model's terms carry, inherited from `old`, what they carried on the mesh this
    /// one's was split from (`node_parent` as in [`term::Term::inherit`]).
    pub fn inherited_history(&self, old: &TermHistory, node_parent: &[usize]) -> TermHistory {
        let mut history = TermHistory::default();
        for term in &self.terms {
            if let Some((name, columns)) = term.carried() {
                history.set(name, columns, term.inherit(old.get(name), node_parent));
            }
        }
        history
    }

    /// Adds contact with rigid obstacles, summed before the other contact terms.
    pub fn add_obstacles(&mut self, contact: Contact) {
        let nodes = self.mesh.num_nodes();
        self.terms
            .insert(0, Box::new(contact::ObstacleContact::new(contact, nodes)));
    }

    /// Replaces the ice–ice contact term.
    pub fn set_ice_contact(&mut self, term: IceContactTerm) {
        self.terms
            .retain(|t| t.as_any().downcast_ref::<IceContactTerm>().is_none());
        self.terms.push(Box::new(term));
    }

    /// The first term of type `T`, if the model has one.
    pub fn term<T: 'static>(&self) -> Option<&T> {
        self.terms
            .iter()
            .find_map(|t| t.as_any().downcast_ref::<T>())
    }

    /// Contact with rigid obstacles, if the scene has any.
    pub fn obstacle_contact(&self) -> Option<&Contact> {
        self.term::<contact::ObstacleContact>().map(|t| &t.contact)
    }

    /// Ice–ice contact, if the mesh has several parts or cracks.
    pub fn ice_contact(&self) -> Option<&IceContact> {
        self.term::<IceContactTerm>()
            .and_then(|t| t.active.as_ref())
    }

    /// Sets the freeze states and expansion in `history` to those of the freezing schedule at
    /// time `t` (s) — of `schedule` where given (a heat solve's over the current step), else
    /// of the scene's. Nothing without freezing.
    pub fn apply_freezing(
        &self,
        t: f64,
        history: &mut ElementHistory,
        schedule: Option<&freezing::Schedule>,
    ) {
        if let Some(f) = &self.freezing {
            f.apply(schedule.unwrap_or(&f.schedule), t, history);
        }
    }

    /// The inelastic strains in `history` brought to the end of a solve with converged
    /// displacements `u` (m), the strain `offsets` of `history` (those of the solve) and the
    /// solve's `creep`: plasticity's return mapping or the solve's creep; returns the largest
    /// inelastic strain norm (0 without plasticity or creep).
    pub fn update_inelastic_strain(
        &self,
        history: &mut ElementHistory,
        offsets: &[crate::fem::StrainOffset],
        u: &[f64],
        creep: Option<&creep::CreepStep>,
    ) -> f64 {
        self.elasticity
            .update_inelastic_strain((history, offsets), &self.mesh.tets, u, creep)
    }

    /// Number of nodes.
    pub fn num_nodes(&self) -> usize {
        self.mesh.num_nodes()
    }

    /// Per-dof constraint mask from the Dirichlet conditions.
    pub fn constrained_dofs(&self) -> Vec<bool> {
        let mut mask = vec![false; 3 * self.num_nodes()];
        for bc in &self.dirichlet {
            bc.mark(&self.mesh, &mut mask);
        }
        mask
    }

    /// Sets the constrained entries of `u` to their prescribed displacement at time `t` (s).
    pub fn apply_dirichlet(&self, t: f64, u: &mut [f64]) {
        for bc in &self.dirichlet {
            bc.apply(&self.mesh, t, u);
        }
    }

    /// Total mass (kg).
    pub fn total_mass(&self) -> f64 {
        self.mass.iter().sum()
    }
}
