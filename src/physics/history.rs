//! Per-element history: what the elements carry from step to step (plastic strain, freeze
//! state, eigenstrain). It is part of the simulation state, so rolling a step back is
//! restoring a copy of the state, and it follows the elements through remeshing.

use crate::fem::StrainOffset;
use nalgebra::Matrix3;

/// The per-element state that changes during a run.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ElementHistory {
    /// Isotropic eigenstrain per element (dimensionless): the scene's prescribed eigenstrain
    /// plus the freezing expansion at the current time.
    pub eigenstrain: Vec<f64>,
    /// Plastic strain per element (symmetric, dimensionless); empty without plasticity.
    pub plastic_strain: Vec<Matrix3<f64>>,
    /// Freeze state per element, 0 (water) … 1 (ice); empty without freezing (all ice).
    pub freeze_state: Vec<f64>,
}

impl ElementHistory {
    /// The history of a mesh's elements at the start of a run: the prescribed `eigenstrain`,
    /// zero plastic strain if `plastic`, no freeze states (a freezing schedule sets them).
    pub fn initial(eigenstrain: &[f64], plastic: bool) -> Self {
        ElementHistory {
            eigenstrain: eigenstrain.to_vec(),
            plastic_strain: if plastic {
                vec![Matrix3::zeros(); eigenstrain.len()]
            } else {
                Vec::new()
            },
            freeze_state: Vec::new(),
        }
    }

    /// The history on a mesh made from this one's by splitting elements: new element `e`
    /// inherits everything element `parent[e]` carries.
    pub fn inherit(&self, parent: &[usize]) -> Self {
        fn pick<T: Copy>(v: &[T], parent: &[usize]) -> Vec<T> {
            if v.is_empty() {
                Vec::new()
            } else {
                parent.iter().map(|&p| v[p]).collect()
            }
        }
        ElementHistory {
            eigenstrain: pick(&self.eigenstrain, parent),
            plastic_strain: pick(&self.plastic_strain, parent),
            freeze_state: pick(&self.freeze_state, parent),
        }
    }

    /// Strain ε* = e I + ε_p of element `e` (its offset without the corotated factor).
    pub fn offset_strain(&self, e: usize) -> Matrix3<f64> {
        let iso = Matrix3::identity() * self.eigenstrain[e];
        match self.plastic_strain.get(e) {
            Some(p) => iso + p,
            None => iso,
        }
    }

    /// Strain offset ε* = e I + ε_p of element `e`.
    pub fn offset_of(&self, e: usize) -> StrainOffset {
        StrainOffset::new(self.offset_strain(e))
    }

    /// The strain offsets of all elements (for a solve, during which they are fixed).
    pub fn offsets(&self) -> Vec<StrainOffset> {
        let n = self.eigenstrain.len();
        if self.plastic_strain.is_empty() && self.eigenstrain.iter().all(|e| *e == 0.0) {
            return vec![StrainOffset::zero(); n];
        }
        crate::parallel::map_range(n, |e| self.offset_of(e))
    }

    /// Brings `offsets` (those of an earlier history of the same elements, or empty) to
    /// [`ElementHistory::offsets`] in place, forming only the offsets whose strain changed
    /// bit for bit: the corotated factor costs an exponential series per element, and from
    /// step to step only the freezing band and the yielding elements change.
    pub fn update_offsets(&self, offsets: &mut Vec<StrainOffset>) {
        if offsets.len() != self.eigenstrain.len() {
            *offsets = self.offsets();
            return;
        }
        if self.plastic_strain.is_empty() && self.eigenstrain.iter().all(|e| *e == 0.0) {
            if offsets.iter().any(|o| !o.is_zero()) {
                offsets.fill(StrainOffset::zero());
            }
            return;
        }
        crate::parallel::for_each_mut(offsets, |e, offset| {
            let strain = self.offset_strain(e);
            if offset.strain != strain {
                *offset = StrainOffset::new(strain);
            }
        });
    }

    /// Whether element `e` holds any ice: its freeze state is above 0 (always, without a
    /// freezing schedule).
    pub fn holds_ice(&self, e: usize) -> bool {
        self.freeze_state.get(e).is_none_or(|&s| s > 0.0)
    }
}
