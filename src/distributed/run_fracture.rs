//! A run's fracture on the processes' parts ([`crate::run::FractureOnParts`]): the driver
//! [`PartFracture`] set up on the part a run starts from.

use super::part_fracture::PartFracture;
use super::splits::SplitPart;
use crate::fracture::cracks::OriginalBoundary;
use crate::fracture::split::Fracturable;
use crate::fracture::{area_floor, FractureReport, FractureSettings};
use crate::mesh::TetMesh;
use crate::run::{CrackTotals, FractureOnParts, FracturePart};
use crate::sim::part::Part;
use crate::sim::{SimError, Simulation};
use mpi::topology::SimpleCommunicator;

/// [`PartFracture`] with the processes it runs on.
pub struct RunFracture<'a> {
    world: &'a SimpleCommunicator,
    fracture: PartFracture,
}

impl<'a> RunFracture<'a> {
    /// Fracture with `settings` of `sim`, built on this process's `part` of the scene's
    /// mesh `mesh` (which every process holds whole), whose nodes' owners and elements'
    /// processes are `owners`. Every process of `world` calls it.
    pub fn new(
        world: &'a SimpleCommunicator,
        settings: FractureSettings,
        (mesh, sim, part): (&TetMesh, &Simulation, &Part),
        (node_owner, process): (Vec<u32>, Vec<u32>),
    ) -> Self {
        let on_part = &sim.model.mesh;
        let (u, v) = (sim.state.u.clone(), sim.state.v.clone());
        let held = SplitPart {
            mesh: Fracturable::new(on_part.rest.clone(), on_part.tets.clone(), u, v),
            node_owner,
            origin: part.elements.clone(),
            process,
            part: part.clone(),
        };
        let all_marks = mesh.boundary_marks();
        let marks: Vec<u8> = part.elements.iter().map(|&e| all_marks[e]).collect();
        let (lo, hi) = mesh.bounding_box();
        let original = OriginalBoundary::of_part(
            on_part,
            (&part.elements, &marks),
            mesh.num_tets(),
            (hi - lo).norm(),
        );
        let floors = (mesh.volume() / mesh.num_tets() as f64, area_floor(mesh));
        let iterative = sim.settings.iterative();
        let solve = (iterative.tolerance, iterative.max_iterations);
        let fracture = PartFracture::new(world, settings, (held, original), floors, solve);
        RunFracture { world, fracture }
    }
}

impl FractureOnParts for RunFracture<'_> {
    fn settings(&self) -> FractureSettings {
        self.fracture.settings
    }

    fn after_step(&mut self, sim: &mut Simulation) -> Result<FractureReport, SimError> {
        self.fracture.after_step(self.world, sim)
    }

    fn part(&self) -> &Part {
        self.fracture.part()
    }

    fn surface_outgrown(&self, sim: &Simulation) -> bool {
        self.fracture.surface_outgrown(self.world, sim)
    }

    fn gather_surface_again(&mut self, sim: &mut Simulation) -> Result<(), SimError> {
        self.fracture.gather_surface_again(self.world, sim)
    }

    fn crack_totals(&self) -> Result<CrackTotals, SimError> {
        self.fracture.crack_totals(self.world)
    }

    fn frame_part(&self, sim: &Simulation) -> Result<FracturePart, SimError> {
        self.fracture.frame_part(self.world, sim)
    }
}
