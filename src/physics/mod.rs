//! The physical model of a scene: elasticity, mass, loads, damping and boundary conditions.
//! A scene builds only the terms it enables; a term that is off costs nothing.

pub mod contact;
pub mod dirichlet;
pub mod elasticity;
pub mod freezing;
pub mod grid;
pub mod ice_contact;
pub mod loads;
pub mod obstacle_mesh;
pub mod plasticity;

pub use contact::{Contact, Obstacle};
pub use dirichlet::Dirichlet;
pub use elasticity::Elasticity;
pub use loads::Traction;

use crate::mesh::{MeshError, TetMesh};
use nalgebra::Vector3;

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
    /// Dead loads (gravity and surface tractions) on every dof (N), length 3 × nodes.
    pub external_force: Vec<f64>,
    /// Rayleigh damping, if any.
    pub damping: Option<Rayleigh>,
    /// Dirichlet conditions.
    pub dirichlet: Vec<Dirichlet>,
    /// Contact with rigid obstacles, if the scene has any (none: no contact work at all).
    pub contact: Option<Contact>,
    /// Contact between separate parts of the mesh, if it has more than one.
    pub ice_contact: Option<ice_contact::IceContact>,
    /// Freezing schedule, if the scene freezes (none: every element is ice throughout).
    pub freezing: Option<freezing::Freezing>,
    /// Plasticity, if on (none: no plastic state at all).
    pub plasticity: Option<plasticity::Plasticity>,
    /// Gravity (m/s²), kept to rebuild the loads after a topology change.
    pub gravity: Vector3<f64>,
    /// Surface tractions, kept likewise.
    pub tractions: Vec<Traction>,
    /// Ice–ice contact parameters for when the mesh has (or fracture makes) several parts:
    /// penalty stiffness (N/m³; 0 = the default 10 E / h), friction, smoothing velocity (m/s).
    pub ice_contact_params: [f64; 3],
}

impl Model {
    /// Assembles the model: lumped mass ρV/4 per tet vertex, gravity m g on each node, the
    /// given tractions on boundary faces.
    pub fn new(
        mesh: TetMesh,
        elasticity: Elasticity,
        gravity: Vector3<f64>,
        tractions: &[Traction],
        damping: Option<Rayleigh>,
        dirichlet: Vec<Dirichlet>,
    ) -> Result<Self, MeshError> {
        let mass = loads::lumped_mass(&mesh, &elasticity.rest, elasticity.material.density);
        let mut external_force = vec![0.0; 3 * mesh.num_nodes()];
        if gravity != Vector3::zeros() {
            loads::add_gravity(&mass, &gravity, &mut external_force);
        }
        for t in tractions {
            loads::add_traction(&mesh, t, &mut external_force);
        }
        Ok(Model {
            mesh,
            elasticity,
            mass,
            external_force,
            damping,
            dirichlet,
            contact: None,
            ice_contact: None,
            freezing: None,
            plasticity: None,
            gravity,
            tractions: tractions.to_vec(),
            ice_contact_params: [0.0, 0.0, 1e-4],
        })
    }

    /// The model on a new mesh made from this one by splitting elements (fracture): `parent[e]`
    /// is the element of this model that new element `e` came from, and inherits its
    /// eigenstrain, plastic strain, freeze state and freezing schedule. Mass and loads are
    /// rebuilt from the new rest volumes and boundary (total mass is unchanged when the rest
    /// volume is), contact from the new boundary, and ice–ice contact from the new parts and
    /// the crack faces `cracks` (node triples; their two sides must not interpenetrate).
    pub fn remeshed(
        &self,
        rest: &[Vector3<f64>],
        tets: Vec<[usize; 4]>,
        parent: &[usize],
        cracks: &[[usize; 3]],
    ) -> Result<Model, MeshError> {
        let rows: Vec<[f64; 3]> = rest.iter().map(|x| [x.x, x.y, x.z]).collect();
        let mesh = TetMesh::from_arrays(&rows, tets)?;
        let old = &self.elasticity;
        let elasticity = old.remeshed(&mesh, parent);
        let inherit = |v: &[f64]| parent.iter().map(|&p| v[p]).collect::<Vec<f64>>();
        let mut model = Model::new(
            mesh,
            elasticity,
            self.gravity,
            &self.tractions,
            self.damping,
            self.dirichlet.clone(),
        )?;
        model.contact = self
            .contact
            .as_ref()
            .map(|c| Contact::new(&model.mesh, c.obstacles.clone(), c.smoothing_velocity));
        let [stiffness, friction, smoothing] = self.ice_contact_params;
        let stiffness = if stiffness > 0.0 {
            stiffness
        } else {
            contact::default_stiffness(&model.mesh, old.material.young())
        };
        model.ice_contact =
            ice_contact::IceContact::new(&model.mesh, stiffness, friction, smoothing, cracks);
        model.ice_contact_params = self.ice_contact_params;
        model.freezing = self.freezing.as_ref().map(|f| freezing::Freezing {
            arrival: inherit(&f.arrival),
            base_eigenstrain: inherit(&f.base_eigenstrain),
            ..f.clone()
        });
        model.plasticity = self.plasticity;
        Ok(model)
    }

    /// Sets the time-dependent material state (freeze states, expansion) for time `t` (s).
    pub fn apply_schedule(&mut self, t: f64) {
        if let Some(f) = &self.freezing {
            f.apply(t, &mut self.elasticity);
        }
    }

    /// Return mapping of the plastic strains for converged displacements `u` (m); returns the
    /// largest plastic strain norm (0 without plasticity).
    pub fn update_plastic_strain(&mut self, u: &[f64]) -> f64 {
        match &self.plasticity {
            Some(p) => p.update(&mut self.elasticity, &self.mesh.tets, u),
            None => 0.0,
        }
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
