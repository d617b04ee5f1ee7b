//! Fracture of a run whose processes each hold a part of the mesh: what the run needs of it
//! (the driver is `distributed::part_fracture`, which the run reaches through
//! [`super::Processes::part_fracture`]), and how a frame puts its pieces together.

use crate::fracture::cracks::CrackSurface;
use crate::fracture::{FractureReport, FractureSettings};
use crate::sim::part::Part;
use crate::sim::{SimError, Simulation};
use nalgebra::Vector3;

/// Fracture of a simulation held in parts by the processes of a run. Every process calls
/// every method, in the same order.
pub trait FractureOnParts {
    /// The parameters.
    fn settings(&self) -> FractureSettings;
    /// Fractures `sim` after a converged step (as [`crate::fracture::Fracture::after_step`]
    /// on one process); the report is the same on every process.
    fn after_step(&mut self, sim: &mut Simulation) -> Result<FractureReport, SimError>;
    /// The simulation's part: it changes with each split and each gathering of the ghost
    /// surface.
    fn part(&self) -> &Part;
    /// Whether the ghost surface held no longer holds what the next step of `sim` needs
    /// (alike on every process).
    fn surface_outgrown(&self, sim: &Simulation) -> bool;
    /// Gathers the ghost surface again at the state of `sim`, which continues on the new part.
    fn gather_surface_again(&mut self, sim: &mut Simulation) -> Result<(), SimError>;
    /// Continues `sim` at a restart point on the part a run resumed there makes from the
    /// frame alone (see [`FractureOnParts::resume`]), so that the resumed run is this one
    /// bit for bit.
    fn restart(&mut self, sim: &mut Simulation) -> Result<(), SimError>;
    /// The whole mesh's cracks, the same on every process.
    fn crack_totals(&self) -> CrackTotals;
    /// What a frame of `sim` holds of fracture on this process's part.
    fn frame_part(&self, sim: &Simulation) -> Result<FracturePart, SimError>;
    /// The process of each element of the scene's mesh, whose split elements stay with it,
    /// and this process's number.
    fn scene_processes(&self) -> (Vec<u32>, u32);
    /// Resumes this fracture, as set up on the scene's parts, from a frame: `sim` is the run
    /// as set up (on [`FractureOnParts::part`], with the frame's temperatures), `split` this
    /// process's part of the frame's split mesh. Returns the run continued on that part with
    /// its ghost surface, its model made from `sim`'s and its heat model linked to it, as a
    /// restart point continues it ([`FractureOnParts::restart`]); the frame's state on
    /// it is the caller's to set.
    fn resume(&mut self, sim: Simulation, split: ResumedSplit) -> Result<Simulation, SimError>;
}

/// A process's part of a resumed frame's split mesh, shared out as the splits share it: each
/// element with the process of its scene element, each node with the lowest process among
/// its elements'; the part holds the process's own elements and every element around their
/// nodes.
#[derive(Clone, Debug, Default)]
pub struct ResumedSplit {
    /// The part (the frame mesh's numbers).
    pub part: Part,
    /// Its nodes' rest positions (m).
    pub rest: Vec<Vector3<f64>>,
    /// Its elements, numbered in the part.
    pub tets: Vec<[usize; 4]>,
    /// Its nodes' displacements (m), 3 a node.
    pub u: Vec<f64>,
    /// Its nodes' velocities (m/s), 3 a node.
    pub v: Vec<f64>,
    /// Its nodes' owners.
    pub node_owner: Vec<u32>,
    /// The scene element each of its elements lies in.
    pub origin: Vec<usize>,
    /// Its elements' processes.
    pub process: Vec<u32>,
    /// Its nodes' refused splits, 4 a node (see
    /// [`crate::fracture::Fracture::refusals_as_rows`]; empty: none).
    pub refused: Vec<f64>,
}

/// The cracks of the whole mesh.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CrackTotals {
    /// Crack faces (both sides).
    pub faces: u64,
    /// Crack area at rest, one side (m²).
    pub area: f64,
    /// Crack polygons (see [`crate::fracture::cracks::crack_polygons`]).
    pub polygons: u64,
}

/// What a frame holds of fracture on a process's part.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FracturePart {
    /// The scene element each element of the part lies in (the frame's `origin`).
    pub origin: Vec<f64>,
    /// The refused splits of the part's nodes, 4 a node (the frame's `refused_split`; see
    /// [`crate::fracture::Fracture::refusals_as_rows`]).
    pub refused: Vec<f64>,
    /// The crack triangles of this process's own elements, [`CRACK_ROW`] values each: the
    /// face's nodes (the mesh's numbers, ascending: what orders the triangles as one process
    /// does), its crack, its three vertices (m).
    pub cracks: Vec<f64>,
    /// The gaps of the pairs of crack copies whose first node this process owns, rows of
    /// (p, q, g) with p, q the mesh's numbers (the frame's `crack_gaps`).
    pub gaps: Vec<f64>,
}

/// Values of one crack triangle in [`FracturePart::cracks`].
pub const CRACK_ROW: usize = 3 + 1 + 9;

/// The crack surface of a frame put together from the processes' crack triangles
/// ([`FracturePart::cracks`]), in the order one process writes them.
pub fn crack_surface(mut rows: Vec<[f64; CRACK_ROW]>) -> CrackSurface {
    // A face's nodes are whole numbers below 2^53, exact as f64.
    rows.sort_by_key(|r| [r[0], r[1], r[2]].map(|x| x as u64));
    let mut surface = CrackSurface::default();
    for (k, row) in rows.iter().enumerate() {
        surface.crack.push(row[3] as usize);
        surface.triangles.push([3 * k, 3 * k + 1, 3 * k + 2]);
        for v in 0..3 {
            surface
                .vertices
                .push([row[4 + 3 * v], row[5 + 3 * v], row[6 + 3 * v]]);
        }
    }
    surface
}

/// The rows of the crack gaps the processes gave ([`FracturePart::gaps`]), in the order of
/// their pairs.
pub fn gap_rows(mut rows: Vec<[f64; 3]>) -> Vec<f64> {
    rows.sort_by_key(|r| [r[0], r[1]].map(|x| x as u64));
    rows.dedup_by(|a, b| a[..2] == b[..2]);
    rows.into_iter().flatten().collect()
}

#[cfg(test)]
mod tests {
    use super::{crack_surface, gap_rows, CRACK_ROW};

    #[test]
    fn the_processes_crack_triangles_and_gaps_come_in_one_processs_order() {
        // Two processes' triangles, given in process order: faces (4, 7, 9) and (1, 2, 8).
        let row = |key: [f64; 3], crack: f64, x: f64| -> [f64; CRACK_ROW] {
            let mut r = [0.0; CRACK_ROW];
            r[..3].copy_from_slice(&key);
            r[3] = crack;
            r[4..].copy_from_slice(&[x; 9]);
            r
        };
        let surface = crack_surface(vec![
            row([4.0, 7.0, 9.0], 1.0, 0.5),
            row([1.0, 2.0, 8.0], 0.0, 0.25),
        ]);
        assert_eq!(surface.crack, [0, 1]);
        assert_eq!(surface.triangles, [[0, 1, 2], [3, 4, 5]]);
        assert_eq!(surface.vertices[0], [0.25; 3]);
        assert_eq!(surface.vertices[5], [0.5; 3]);
        // A pair given by two processes is written once, pairs by their nodes.
        let gaps = gap_rows(vec![[5.0, 9.0, 0.1], [2.0, 3.0, 0.2], [5.0, 9.0, 0.1]]);
        assert_eq!(gaps, [2.0, 3.0, 0.2, 5.0, 9.0, 0.1]);
    }
}
