//! Locking-free volumetric response of linear tets: the average nodal pressure of Bonet &
//! Burton (1998).
//!
//! A linear tet has one volume change θₑ, and a mesh has about five times as many tets as
//! nodes: when the volume is (nearly) fixed — ice flowing plastically, which keeps its volume,
//! or water, whose shear stiffness is 1e-4 of its bulk — those constraints outnumber the free
//! displacements and the mesh locks: it is far too stiff, and the pressure varies wildly
//! from element to element (7.5 × its smooth part in the freezing container), which the
//! fracture criterion reads as separation. Averaging the volume change over the elements
//! around each node leaves about one constraint per node:
//!
//! ```text
//! θ̄ₐ = Σₑ∋ₐ wₐₑ θₑ,   wₐₑ = (Vₑ/4) / Vₐ,   Vₐ = Σₑ∋ₐ Vₑ/4,
//! U_vol = Σₐ Vₐ κₐ/2 θ̄ₐ²,   κₐ = Σₑ∋ₐ wₐₑ κₑ,
//! ```
//!
//! with κₑ the element's bulk modulus (its ice's K plus its water's) and θₑ the volume change of
//! its elastic deformation (`fem::ElasticLaw::volume_change`: tr ε − tr ε* linear, det Fe − 1
//! corotated). The elements then carry only the deviatoric energy. The nodal forces are those of an
//! element pressure p̄ₑ = ¼ Σₐ∈ₑ κₐ θ̄ₐ acting through θₑ, so an element's stress is its deviatoric
//! stress plus p̄ₑ and the nodal force balance the fracture criterion relies on holds element by
//! element. The Hessian Σₐ Vₐ κₐ ∇θ̄ₐ ∇θ̄ₐᵀ (plus p̄ₑ ∂²θₑ for the corotated model) couples every
//! pair of nodes of a node's star, so the sparsity pattern gains those pairs
//! ([`NodalVolume::couplings`]).

use crate::assembly::Assembly;
use crate::fem::{ElementRest, VolumeChange};
use crate::mesh::TetMesh;

/// Where a node's star and its Hessian blocks are.
#[derive(Clone, Debug, Default)]
pub struct NodalVolume {
    /// Elements around each node: `star[star_ptr[a]..star_ptr[a + 1]]`.
    star_ptr: Vec<usize>,
    star: Vec<u32>,
    /// Vₐ (m³).
    node_volume: Vec<f64>,
    /// Nodes of each node's star, sorted: `ring[ring_ptr[a]..ring_ptr[a + 1]]`.
    ring_ptr: Vec<usize>,
    ring: Vec<u32>,
    /// For each element around a node (aligned with `star`), the positions of its four
    /// vertices in the node's ring.
    local: Vec<[u16; 4]>,
    /// Value slots of the ring's dof pairs, (3 r)² per node of ring size r, row-major with
    /// u32::MAX for constrained dofs: `slots[slot_ptr[a]..]`.
    slot_ptr: Vec<usize>,
    slots: Vec<u32>,
}

impl NodalVolume {
    /// The stars of `mesh`'s nodes, with rest data `rest`.
    pub fn new(mesh: &TetMesh, rest: &[ElementRest]) -> Self {
        let n = mesh.num_nodes();
        let adjacency = mesh.node_to_tets();
        let mut v = NodalVolume {
            star_ptr: vec![0],
            ring_ptr: vec![0],
            ..Default::default()
        };
        for a in 0..n {
            let elements: Vec<u32> = adjacency.of(a).iter().map(|&(t, _)| t).collect();
            let mut ring: Vec<u32> = elements
                .iter()
                .flat_map(|&e| mesh.tets[e as usize].map(|i| i as u32))
                .collect();
            ring.sort_unstable();
            ring.dedup();
            for &e in &elements {
                let tet = mesh.tets[e as usize];
                // Every vertex of the star's elements is in the ring by construction.
                v.local
                    .push(tet.map(|i| ring.binary_search(&(i as u32)).unwrap_or(0) as u16));
            }
            v.node_volume.push(
                elements
                    .iter()
                    .map(|&e| rest[e as usize].volume / 4.0)
                    .sum(),
            );
            v.star.extend(elements);
            v.star_ptr.push(v.star.len());
            v.ring.extend(ring);
            v.ring_ptr.push(v.ring.len());
        }
        v
    }

    /// The node pairs the volumetric Hessian couples: every pair within a node's star.
    pub fn couplings(&self) -> Vec<(usize, usize)> {
        let mut pairs = Vec::new();
        for a in 0..self.node_volume.len() {
            let ring = &self.ring[self.ring_ptr[a]..self.ring_ptr[a + 1]];
            for (k, &b) in ring.iter().enumerate() {
                for &c in &ring[k + 1..] {
                    pairs.push((b as usize, c as usize));
                }
            }
        }
        pairs.sort_unstable();
        pairs.dedup();
        pairs
    }

    /// Finds the value slots of every node's ring blocks in `assembly`'s pattern, which must
    /// contain [`NodalVolume::couplings`].
    pub fn pattern_ready(&mut self, assembly: &Assembly) {
        let dofs = assembly.dofs();
        self.slots.clear();
        self.slot_ptr = vec![0];
        for a in 0..self.node_volume.len() {
            let ring = &self.ring[self.ring_ptr[a]..self.ring_ptr[a + 1]];
            let free: Vec<Option<usize>> = ring
                .iter()
                .flat_map(|&b| (0..3).map(move |k| dofs.free(3 * b as usize + k)))
                .collect();
            for row in &free {
                for col in &free {
                    let slot = match (row, col) {
                        (Some(r), Some(c)) => assembly.slot(*r, *c).map_or(u32::MAX, |s| s as u32),
                        _ => u32::MAX,
                    };
                    self.slots.push(slot);
                }
            }
            self.slot_ptr.push(self.slots.len());
        }
    }

    /// Element pressures p̄ₑ (Pa) for element volume changes `theta` and bulk moduli `bulk`
    /// (Pa), and the volumetric energy U_vol (J).
    pub fn pressures(
        &self,
        theta: &[f64],
        bulk: &[f64],
        rest: &[ElementRest],
        tets: &[[usize; 4]],
        owned: Option<&[bool]>,
    ) -> (Vec<f64>, f64) {
        let (node_pressure, energy) = self.node_pressures(theta, bulk, rest, owned);
        (element_pressures(&node_pressure, tets), energy)
    }

    /// Nodal pressures pₐ = κₐ θ̄ₐ (Pa) for element volume changes `theta` and bulk moduli
    /// `bulk` (Pa), and the volumetric energy U_vol (J) of the nodes whose dofs `owned` marks
    /// (all if `None`).
    pub fn node_pressures(
        &self,
        theta: &[f64],
        bulk: &[f64],
        rest: &[ElementRest],
        owned: Option<&[bool]>,
    ) -> (Vec<f64>, f64) {
        let mut node_pressure = vec![0.0; self.node_volume.len()];
        let mut energy = 0.0;
        for (a, p) in node_pressure.iter_mut().enumerate() {
            let va = self.node_volume[a];
            if va <= 0.0 {
                continue;
            }
            let (mut t, mut k) = (0.0, 0.0);
            for &e in &self.star[self.star_ptr[a]..self.star_ptr[a + 1]] {
                let w = rest[e as usize].volume / 4.0 / va;
                t += w * theta[e as usize];
                k += w * bulk[e as usize];
            }
            *p = k * t;
            if owned.is_none_or(|owned| owned[3 * a]) {
                energy += 0.5 * va * k * t * t;
            }
        }
        (node_pressure, energy)
    }

    /// Adds Σₐ Vₐ κₐ ∇θ̄ₐ ∇θ̄ₐᵀ to the CSC values `hessian`, for the elements' volume changes
    /// `change` and bulk moduli `bulk` (Pa). Sequential: nodes with overlapping stars write the
    /// same entries (one copy of the values per thread, summed afterwards, cost as much as it
    /// saved at 10 368 tets).
    pub fn add_hessian(
        &self,
        change: &[VolumeChange],
        bulk: &[f64],
        rest: &[ElementRest],
        hessian: &mut [f64],
        owned: Option<&[bool]>,
    ) {
        let mut grad: Vec<f64> = Vec::new();
        for a in 0..self.node_volume.len() {
            let va = self.node_volume[a];
            let r = self.ring_ptr[a + 1] - self.ring_ptr[a];
            if va <= 0.0 || owned.is_some_and(|owned| !owned[3 * a]) {
                continue;
            }
            grad.clear();
            grad.resize(3 * r, 0.0);
            let mut k = 0.0;
            for (s, &e) in (self.star_ptr[a]..self.star_ptr[a + 1])
                .zip(&self.star[self.star_ptr[a]..self.star_ptr[a + 1]])
            {
                let e = e as usize;
                let w = rest[e].volume / 4.0 / va;
                k += w * bulk[e];
                let g = change[e].nodal_gradient(&rest[e]);
                for (vertex, &pos) in self.local[s].iter().enumerate() {
                    for d in 0..3 {
                        grad[3 * pos as usize + d] += w * g[3 * vertex + d];
                    }
                }
            }
            let scale = va * k;
            if scale == 0.0 {
                continue;
            }
            let slots = &self.slots[self.slot_ptr[a]..self.slot_ptr[a + 1]];
            for (i, gi) in grad.iter().enumerate() {
                if *gi == 0.0 {
                    continue;
                }
                let row = &slots[i * 3 * r..(i + 1) * 3 * r];
                for (&slot, gj) in row.iter().zip(&grad) {
                    if slot != u32::MAX {
                        hessian[slot as usize] += scale * gi * gj;
                    }
                }
            }
        }
    }
}

/// Element pressures p̄ₑ = ¼ Σₐ pₐ (Pa) over the element's nodes, from the nodal pressures
/// `node_pressure` (Pa).
pub fn element_pressures(node_pressure: &[f64], tets: &[[usize; 4]]) -> Vec<f64> {
    tets.iter()
        .map(|tet| tet.iter().map(|&a| node_pressure[a]).sum::<f64>() / 4.0)
        .collect()
}
