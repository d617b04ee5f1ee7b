//! A run's fracture on the processes' parts ([`crate::run::FractureOnParts`]): the driver
//! [`PartFracture`] set up on the part a run starts from.

use super::part_fracture::PartFracture;
use super::splits::SplitPart;
use crate::fracture::cracks::OriginalBoundary;
use crate::fracture::split::Fracturable;
use crate::fracture::{area_floor, Fracture, FractureReport, FractureSettings};
use crate::mesh::TetMesh;
use crate::run::{CrackTotals, FractureOnParts, FracturePart};
use crate::sim::part::Part;
use crate::sim::{SimError, Simulation};
use crate::thermal::HeatLink;
use mpi::topology::SimpleCommunicator;

/// [`PartFracture`] with the processes it runs on.
pub struct RunFracture<'a> {
    world: &'a SimpleCommunicator,
    fracture: PartFracture,
}

impl<'a> RunFracture<'a> {
    /// Fracture with `settings` of `sim`, built on this process's `part` of the scene's
    /// mesh `mesh` (which every process holds whole), whose nodes' owners and elements'
    /// processes are `owners`; with ice–ice contact `sim` continues on the part and a ghost
    /// surface the fracture holds (see [`PartFracture::new`]). Every process of `world`
    /// calls it.
    pub fn new(
        world: &'a SimpleCommunicator,
        settings: FractureSettings,
        (mesh, sim, part): (&TetMesh, &mut Simulation, &Part),
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
        let (original, floors) = of_scene(mesh, part);
        let solve = solve_of(sim);
        let fracture =
            PartFracture::new(world, settings, (on_sim, original), floors, (solve, sim))?;
        Ok(RunFracture { world, fracture })
    }

    /// Fracture with `settings` resumed from a frame: `whole` is the simulation of the
    /// frame's split mesh on the whole mesh and its fracture; this process's part of the
    /// scene's mesh `mesh` is `part`, `scene_process` the process of each scene element and
    /// `heat` the heat model on `part` at the frame's temperatures, with `[thermal]` (see
    /// [`PartFracture::resumed`]). Returns it with the simulation continued on this
    /// process's part of the split mesh. Every process of `world` calls it.
    pub fn resumed(
        world: &'a SimpleCommunicator,
        settings: FractureSettings,
        (mesh, part): (&TetMesh, &Part),
        whole: (Simulation, &Fracture),
        (scene_process, heat): (&[u32], Option<HeatLink>),
    ) -> Result<(Self, Simulation), SimError> {
        let (original, floors) = of_scene(mesh, part);
        let solve = solve_of(&whole.0);
        let (fracture, sim) = PartFracture::resumed(
            world,
            (settings, original),
            whole,
            (scene_process, part.clone(), heat),
            floors,
            solve,
        )?;
        Ok((RunFracture { world, fracture }, sim))
    }
}

/// The scene's boundary planes of this process's `part` of the scene mesh `mesh`, and the
/// whole scene mesh's smallest piece (m³) and area floor (m²) (see [`PartFracture::new`]).
fn of_scene(mesh: &TetMesh, part: &Part) -> (OriginalBoundary, (f64, f64)) {
    let all_marks = mesh.boundary_marks();
    let marks: Vec<u8> = part.elements.iter().map(|&e| all_marks[e]).collect();
    let (lo, hi) = mesh.bounding_box();
    let on_part = TetMesh {
        rest: part.nodes.iter().map(|&i| mesh.rest[i]).collect(),
        tets: part.tets_of(&mesh.tets),
    };
    let original = OriginalBoundary::of_part(
        &on_part,
        (&part.elements, &marks),
        mesh.num_tets(),
        (hi - lo).norm(),
    );
    let floors = (mesh.volume() / mesh.num_tets() as f64, area_floor(mesh));
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
}
