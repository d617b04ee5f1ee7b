//! A run's fracture on the processes' parts ([`crate::run::FractureOnParts`]): the driver
//! [`PartFracture`] set up on the part a run starts from.

use super::part_fracture::PartFracture;
use super::splits::SplitPart;
use super::{largest, sum_in_order};
use crate::fracture::cracks::OriginalBoundary;
use crate::fracture::split::Fracturable;
use crate::fracture::{area_floor_of, FractureReport, FractureSettings};
use crate::mesh::TetMesh;
use crate::run::{CrackTotals, FractureOnParts, FracturePart, ResumedSplit};
use crate::sim::part::Part;
use crate::sim::{SimError, Simulation};
use mpi::topology::SimpleCommunicator;
use mpi::traits::Communicator;

/// [`PartFracture`] with the processes it runs on.
pub struct RunFracture<'a> {
    world: &'a SimpleCommunicator,
    fracture: PartFracture,
}

impl<'a> RunFracture<'a> {
    /// Fracture with `settings` of `sim`, built on this process's `part` of the scene's
    /// mesh, whose nodes' owners and elements' processes are `owners`; with ice–ice contact
    /// `sim` continues on the part and a ghost surface the fracture holds (see
    /// [`PartFracture::new`]). Every process of `world` calls it.
    pub fn new(
        world: &'a SimpleCommunicator,
        settings: FractureSettings,
        (sim, part): (&mut Simulation, &Part),
        (node_owner, process): (Vec<u32>, Vec<u32>),
    ) -> Result<Self, SimError> {
        let on_part = &sim.model.mesh;
        let (u, v) = (sim.state.u.clone(), sim.state.v.clone());
        let on_sim = SplitPart {
            mesh: Fracturable::new(on_part.rest.clone(), on_part.tets.clone(), u, v),
            node_owner,
            origin: part.elements.clone(),
            process,
            part: part.clone(),
        };
        let (original, floors) = of_scene(world, &sim.model.mesh, part);
        let solve = solve_of(sim);
        let fracture =
            PartFracture::new(world, settings, (on_sim, original), floors, (solve, sim))?;
        Ok(RunFracture { world, fracture })
    }
}

/// The scene's boundary planes of this process's `part` of the scene's mesh, of mesh `mesh`
/// (numbered in the part), and the whole scene mesh's smallest piece (m³) and area floor
/// (m²) (see [`PartFracture::new`]), from sums and maxima over the processes of `world`,
/// which all call it.
///
/// The planes are those of the part's boundary faces: the whole boundary's and the faces
/// where the part is cut off. A cut face is never a face of an element the process
/// evaluates, nor through a node of one (every element around such a node is held), and
/// the crack faces that count are only those (see [`PartFracture`]): a cut face taken for
/// the scene's boundary changes nothing there.
fn of_scene(
    world: &SimpleCommunicator,
    mesh: &TetMesh,
    part: &Part,
) -> (OriginalBoundary, (f64, f64)) {
    let (lo, hi) = mesh.bounding_box();
    let (lo, hi) = (
        lo.map(|x| -largest(world, -x)),
        hi.map(|x| largest(world, x)),
    );
    let elements = part.whole_elements();
    let original = OriginalBoundary::of_part(
        mesh,
        (&part.elements, &mesh.boundary_marks()),
        elements,
        (hi - lo).norm(),
    );
    let own_volume: f64 = (0..mesh.num_tets())
        .filter(|&e| part.own_elements[e])
        .map(|e| mesh.signed_volume(e))
        .sum();
    let volume = sum_in_order(world, own_volume);
    let floors = (volume / elements as f64, area_floor_of(volume, elements));
    (original, floors)
}

/// CG's relative tolerance and iteration cap of `sim`'s shared solver.
fn solve_of(sim: &Simulation) -> (f64, usize) {
    let iterative = sim.settings.iterative();
    (iterative.tolerance, iterative.max_iterations)
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

    fn restart(&mut self, sim: &mut Simulation) -> Result<(), SimError> {
        self.fracture.restart(self.world, sim)
    }

    fn crack_totals(&self) -> CrackTotals {
        self.fracture.crack_totals()
    }

    fn frame_part(&self, sim: &Simulation) -> Result<FracturePart, SimError> {
        self.fracture.frame_part(self.world, sim)
    }

    fn scene_processes(&self) -> (Vec<u32>, u32) {
        (
            self.fracture.scene_processes(self.world),
            self.world.rank() as u32,
        )
    }

    fn resume(&mut self, sim: Simulation, split: ResumedSplit) -> Result<Simulation, SimError> {
        let (fracture, sim) = self.fracture.resumed(self.world, sim, split)?;
        self.fracture = fracture;
        Ok(sim)
    }
}
