//! Elastic energy of the mesh: per-element rest data, material, model and strain offsets.
//!
//! Each element's stress is σ = C : (ε − ε*) with the strain offset ε* = e I + ε_p: an
//! isotropic eigenstrain e (a scene's `[[eigenstrain]]` plus the freezing expansion) and, with
//! plasticity or creep on, the element's inelastic strain ε_p. With plasticity an element
//! containing ice yields inside the solve, with creep it creeps over the solve: its energy is
//! the incremental potential of the return mapping (`fem::solid_response`), so the converged
//! stress is on the yield surface, or has crept. While freezing,
//! an element's material blends from water to ice with its freeze state. The strain offsets
//! and freeze states are per-element history and live in the simulation state
//! ([`ElementHistory`]).

use super::creep::{Creep, CreepStep};
use super::history::ElementHistory;
use super::plasticity::Plasticity;
use super::term::StepTerm;
use super::volumetric::{self, NodalVolume};
use crate::assembly::{Assembly, ElementSubset};
use crate::fem::{
    element_eval, element_stress, ElasticLaw, ElasticModel, ElementEval, ElementRest, Flow, Law,
    Material, StrainOffset, VolumeChange,
};
use crate::mesh::TetMesh;
use nalgebra::{Matrix3, Vector3};

/// How the volumetric part of the elastic energy is discretised.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Volumetric {
    /// Per element: the plain linear tet (it locks when the volume is nearly fixed).
    #[default]
    Element,
    /// Averaged at the nodes (Bonet & Burton's average nodal pressure; see `volumetric`).
    Nodal,
}

/// The elastic term: the materials of the elements (the ice, and others where the scene
/// says), one strain measure for all, their rest data, and the scene's prescribed eigenstrain.
#[derive(Clone, Debug)]
pub struct Elasticity {
    /// Material constants of the ice (Pa, kg/m³): the scene's `[material]`, that of every
    /// element `material_index` gives no other.
    pub material: Material,
    /// Further materials (`[materials.NAME]`), numbered from 1 in `material_index`.
    pub other_materials: Vec<Material>,
    /// Per element: 0 for `material`, k for `other_materials[k − 1]`; empty: all `material`.
    pub material_index: Vec<u16>,
    /// Strain measure: the scene's elastic model, whose law [`Elasticity::law`] gives.
    pub model: ElasticModel,
    /// Rest data per element; empty in a scene's model, which only describes the elements
    /// (see [`Elasticity::described`]) until a simulation builds it.
    pub rest: Vec<ElementRest>,
    /// Prescribed isotropic eigenstrain per element (dimensionless), the scene's
    /// `[[eigenstrain]]`: the initial value of the history's eigenstrain, to which freezing
    /// adds its expansion.
    pub eigenstrain: Vec<f64>,
    /// Bulk modulus of unfrozen water (Pa; 0 for inactive water); used only for elements
    /// whose freeze state is below 1.
    pub water_bulk: f64,
    /// Regularising shear modulus of unfrozen water (Pa), see `freezing`.
    pub water_shear: f64,
    /// Plasticity, if on (none: no plastic state at all).
    pub plasticity: Option<Plasticity>,
    /// Creep, if on (exclusive with plasticity: the inelastic strain is the crept one).
    pub creep: Option<Creep>,
    /// Whether ice forms in water (`[freezing] expansion = "displaces_water"`, see
    /// `ice_formation`): the inelastic strain then also carries what the ice was born with
    /// and the water's swelling.
    pub ice_formation: bool,
    /// The volumetric discretisation.
    volumetric: Volumetric,
    /// The nodal averaging of the volumetric energy, if on (`[material] volumetric =
    /// "nodal"`; none: per element, or where the elements' rest data is not built).
    pub nodal: Option<NodalVolume>,
}

impl Elasticity {
    /// Elasticity of `mesh` with zero eigenstrain and no water.
    pub fn new(mesh: &TetMesh, material: Material, model: ElasticModel) -> Self {
        let mut elasticity = Self::described(mesh, material, model);
        elasticity.rest = ElementRest::of_mesh(mesh);
        elasticity
    }

    /// As [`Elasticity::new`], without the elements' rest data (104 bytes an element, most of
    /// a model) or the nodal averaging built on it: what the elements are made of and how
    /// they are discretised — a scene's model. The simulation builds the rest data on the
    /// mesh it runs ([`Elasticity::build`]): one process for the whole mesh, once; each
    /// process of a distributed run for its part's elements only ([`Elasticity::remeshed`]),
    /// so that none builds the whole mesh's.
    pub fn described(mesh: &TetMesh, material: Material, model: ElasticModel) -> Self {
        Elasticity {
            material,
            other_materials: Vec::new(),
            material_index: Vec::new(),
            model,
            rest: Vec::new(),
            eigenstrain: vec![0.0; mesh.num_tets()],
            water_bulk: 0.0,
            water_shear: 0.0,
            plasticity: None,
            creep: None,
            ice_formation: false,
            volumetric: Volumetric::Element,
            nodal: None,
        }
    }

    /// Whether the elements' rest data is built (see [`Elasticity::described`]).
    pub fn is_built(&self) -> bool {
        self.rest.len() == self.eigenstrain.len()
    }

    /// Builds the rest data of `mesh`'s elements and the nodal averaging if the scene asks
    /// for it, unless built already.
    pub fn build(&mut self, mesh: &TetMesh) {
        if !self.is_built() {
            self.rest = ElementRest::of_mesh(mesh);
            self.set_volumetric(mesh, self.volumetric);
        }
    }

    /// Switches the volumetric discretisation of this elasticity on `mesh` (the nodal
    /// averaging is built with the elements' rest data).
    pub fn set_volumetric(&mut self, mesh: &TetMesh, volumetric: Volumetric) {
        self.volumetric = volumetric;
        self.nodal = match volumetric {
            Volumetric::Nodal if self.is_built() => Some(NodalVolume::new(mesh, &self.rest)),
            _ => None,
        };
    }

    /// The volumetric discretisation.
    pub fn volumetric(&self) -> Volumetric {
        self.volumetric
    }

    /// Node pairs the elastic energy couples beyond the elements (the nodal volumetric
    /// energy's stars; none per element).
    pub fn couplings(&self) -> Vec<(usize, usize)> {
        self.nodal.as_ref().map_or(Vec::new(), |n| n.couplings())
    }

    /// Lets the nodal volumetric energy find its slots in a new pattern.
    pub fn pattern_ready(&mut self, assembly: &Assembly) {
        if let Some(n) = &mut self.nodal {
            n.pattern_ready(assembly);
        }
    }

    /// This elasticity on `mesh`, made from this one's mesh by splitting elements: new element
    /// `e` inherits the prescribed eigenstrain of element `parent[e]`.
    pub fn remeshed(&self, mesh: &TetMesh, parent: &[usize]) -> Self {
        let inherit = |v: &[u16]| parent.iter().map(|&p| v[p]).collect();
        let mut el = Elasticity {
            rest: ElementRest::of_mesh(mesh),
            eigenstrain: parent.iter().map(|&p| self.eigenstrain[p]).collect(),
            material_index: if self.material_index.is_empty() {
                Vec::new()
            } else {
                inherit(&self.material_index)
            },
            other_materials: self.other_materials.clone(),
            volumetric: self.volumetric,
            nodal: None,
            material: self.material,
            model: self.model,
            water_bulk: self.water_bulk,
            water_shear: self.water_shear,
            plasticity: self.plasticity,
            creep: self.creep,
            ice_formation: self.ice_formation,
        };
        el.set_volumetric(mesh, self.volumetric());
        el
    }

    /// Whether the elements carry an inelastic strain: with plasticity, creep or ice that
    /// forms in water.
    pub fn inelastic(&self) -> bool {
        self.plasticity.is_some() || self.creep.is_some() || self.ice_formation
    }

    /// The history of these elements at the start of a run without freezing: the prescribed
    /// eigenstrain, and zero inelastic strain with plasticity, creep or ice formation.
    pub fn initial_history(&self) -> ElementHistory {
        ElementHistory::initial(&self.eigenstrain, self.inelastic())
    }

    /// The law of the elastic model (strain measure and response), resolved from
    /// [`Elasticity::model`].
    #[inline]
    pub fn law(&self) -> &'static dyn ElasticLaw {
        self.model.law()
    }

    /// Displacements of the four vertices of `tet` from the global dof vector `u` (m).
    pub fn local(u: &[f64], tet: &[usize; 4]) -> [Vector3<f64>; 4] {
        tet.map(|v| Vector3::new(u[3 * v], u[3 * v + 1], u[3 * v + 2]))
    }

    /// The material element `e` is made of (frozen, where it freezes).
    pub fn base_material(&self, e: usize) -> Material {
        match self.material_index.get(e) {
            Some(&k) if k > 0 => self.other_materials[k as usize - 1],
            _ => self.material,
        }
    }

    /// Material of element `e` and the bulk modulus (Pa) of its water part: its material and
    /// none, or, while it freezes at state s, s × the ice's Lamé constants (plus (1 − s) ×
    /// the water's regularising shear modulus) and (1 − s) × the water's bulk modulus, so its
    /// stiffness changes continuously (the paper's blend: the mean of the phases' moduli).
    ///
    /// Where ice forms in water (`ice_formation`, with bulk water) the blend is the harmonic
    /// mean instead, ice and water in series: K = 1/(s/K_ice + (1 − s)/K_water), and μ the
    /// same with the water's regularising shear modulus. A partly frozen element is then as
    /// soft in shear as its water until it is nearly all ice (μ = 0.01 μ_ice at s = 0.99 with
    /// the default regularisation): slush, and the water beside a front crossing the element,
    /// flow, where the mean made a band of elements at s = 0.05 a wall of 170 MPa shear
    /// stiffness that trapped the water behind it. All of K acts through the water's law
    /// (K/2 (J − 1)², exact in volume), the solid's is shear alone.
    pub fn material_of(&self, history: &ElementHistory, e: usize) -> (Material, f64) {
        let base = self.base_material(e);
        match history.freeze_state.get(e) {
            Some(&s) if s < 1.0 && self.ice_formation && self.water_bulk > 0.0 => {
                let bulk = 1.0 / (s / base.bulk() + (1.0 - s) / self.water_bulk);
                let mu = if self.water_shear > 0.0 {
                    1.0 / (s / base.mu + (1.0 - s) / self.water_shear)
                } else {
                    0.0
                };
                (
                    Material {
                        lambda: -2.0 * mu / 3.0,
                        mu,
                        density: base.density,
                    },
                    bulk,
                )
            }
            Some(&s) if s < 1.0 => (
                Material {
                    lambda: s * base.lambda,
                    mu: s * base.mu + (1.0 - s) * self.water_shear,
                    density: base.density,
                },
                (1.0 - s) * self.water_bulk,
            ),
            _ => (base, 0.0),
        }
    }

    /// The constitutive law of element `e`: its material and water (see
    /// [`Elasticity::material_of`]) and, with plasticity, its elastic limit if it contains ice
    /// (freeze state above 0: a partly frozen element yields at its ice's share of the yield
    /// stress, 2 μ_s γ) and its plastic strain is below the cap, if the scene sets one (a
    /// capped element is elastic).
    ///
    /// With the nodal volumetric energy the element's law is deviatoric only (K = 0: λ = −2μ/3,
    /// no water): its volumetric part is [`Elasticity::bulk_of`], averaged at the nodes.
    pub fn law_of(&self, history: &ElementHistory, e: usize) -> Law {
        let (mut material, mut water_bulk) = self.material_of(history, e);
        if self.nodal.is_some() {
            material.lambda = -2.0 * material.mu / 3.0;
            water_bulk = 0.0;
        }
        let flow = self.plasticity.and_then(|p| {
            let plastic = history.plastic_strain.get(e)?;
            let below_cap = p.cap.is_none_or(|cap| plastic.norm() < cap);
            (history.holds_ice(e) && below_cap).then_some(Flow::Yield(p.elastic_limit))
        });
        Law {
            model: self.law(),
            material,
            water_bulk,
            flow,
        }
    }

    /// The law of element `e` inside a solve: [`Elasticity::law_of`], and with creep, if the
    /// element holds ice of `[material]` (other materials do not creep), its creep over the
    /// solve `creep` (none: a solve without creep, as for the stiffness of Rayleigh damping).
    /// Creep acts only inside a solve: after it, [`Elasticity::update_inelastic_strain`]
    /// moves the crept strain into the history.
    pub fn law_in_solve(
        &self,
        history: &ElementHistory,
        e: usize,
        creep: Option<&CreepStep>,
    ) -> Law {
        let mut law = self.law_of(history, e);
        if let (Some(c), Some(step)) = (&self.creep, creep) {
            let ice = self.material_index.get(e).is_none_or(|&k| k == 0);
            if ice && history.holds_ice(e) {
                law.flow = Some(c.flow(step.compliance[e]));
            }
        }
        law
    }

    /// The bulk modulus of element `e` (Pa): its solid's K = λ + 2μ/3 plus its water's.
    pub fn bulk_of(&self, history: &ElementHistory, e: usize) -> f64 {
        let (material, water_bulk) = self.material_of(history, e);
        material.bulk() + water_bulk
    }

    /// The volume changes and bulk moduli of every element at `u`, for the nodal volumetric
    /// energy.
    fn volume_changes(
        &self,
        tets: &[[usize; 4]],
        history: &ElementHistory,
        offsets: &[StrainOffset],
        u: &[f64],
        with_hessian: bool,
    ) -> (Vec<VolumeChange>, Vec<f64>) {
        crate::parallel::map_range(tets.len(), |e| {
            let rest = &self.rest[e];
            let grad_u = rest.displacement_gradient(&Self::local(u, &tets[e]));
            let change = self.law().volume_change(&grad_u, &offsets[e], with_hessian);
            (change, self.bulk_of(history, e))
        })
        .into_iter()
        .unzip()
    }

    /// With the nodal volumetric energy: each element's pressure p̄ₑ (Pa) at `u`, and the
    /// volumetric energy (J) — of the nodes whose dofs `owned` marks, if given; none per
    /// element.
    pub fn nodal_pressures(
        &self,
        tets: &[[usize; 4]],
        history: &ElementHistory,
        offsets: &[StrainOffset],
        u: &[f64],
        owned: Option<&[bool]>,
    ) -> Option<(Vec<f64>, f64)> {
        let nodal = self.nodal.as_ref()?;
        let (change, bulk) = self.volume_changes(tets, history, offsets, u, false);
        let theta: Vec<f64> = change.iter().map(|c| c.theta).collect();
        Some(nodal.pressures(&theta, &bulk, &self.rest, tets, owned))
    }

    /// As [`Elasticity::nodal_pressures`], the element pressures only, with the nodal
    /// pressures passed through `from_owners` before they are averaged over the elements: on
    /// a process's part, a node's pressure is whole only where the part holds its star (at
    /// the nodes of its own elements), and `from_owners` gives every node its owner's.
    pub fn element_pressures_from_owners(
        &self,
        tets: &[[usize; 4]],
        history: &ElementHistory,
        offsets: &[StrainOffset],
        u: &[f64],
        from_owners: &dyn Fn(&mut [f64]),
    ) -> Option<Vec<f64>> {
        let nodal = self.nodal.as_ref()?;
        let (change, bulk) = self.volume_changes(tets, history, offsets, u, false);
        let theta: Vec<f64> = change.iter().map(|c| c.theta).collect();
        let (mut node_pressure, _) = nodal.node_pressures(&theta, &bulk, &self.rest, None);
        from_owners(&mut node_pressure);
        Some(volumetric::element_pressures(&node_pressure, tets))
    }

    /// Energy, gradient and optionally the exact stiffness of element `e` for displacements `u`.
    pub fn element(
        &self,
        tets: &[[usize; 4]],
        history: &ElementHistory,
        u: &[f64],
        e: usize,
        with_hessian: bool,
        out: &mut ElementEval,
    ) {
        let offset = history.offset_of(e);
        let law = self.law_of(history, e);
        self.element_with(tets, &law, u, e, &offset, with_hessian, false, out);
    }

    /// As [`Elasticity::element`], with the element's `law` and strain `offset` given; with
    /// `project` the stiffness is made positive semi-definite (see `fem::ElasticLaw::solid`).
    // The element's inputs: mesh, law, state, which element and what to compute.
    #[allow(clippy::too_many_arguments)]
    pub fn element_with(
        &self,
        tets: &[[usize; 4]],
        law: &Law,
        u: &[f64],
        e: usize,
        offset: &StrainOffset,
        with_hessian: bool,
        project: bool,
        out: &mut ElementEval,
    ) {
        element_eval(
            law,
            &self.rest[e],
            &Self::local(u, &tets[e]),
            offset,
            with_hessian,
            project,
            out,
        );
    }

    /// The largest nodal force (N) the strain offsets would exert on a clamped mesh,
    /// |V (C:ε*) ∇Nᵢ| over elements and nodes: the expansion and plastic strain act as loads,
    /// and Newton judges its residual against this scale like against dead loads.
    pub fn offset_force_scale(&self, history: &ElementHistory) -> f64 {
        (0..self.rest.len())
            .filter(|&e| history.eigenstrain[e] != 0.0 || !history.plastic_strain.is_empty())
            .map(|e| {
                let (material, water_bulk) = self.material_of(history, e);
                let offset = history.offset_strain(e);
                let stress =
                    material.hooke(&offset) + Matrix3::identity() * (water_bulk * offset.trace());
                let r = &self.rest[e];
                r.grads
                    .iter()
                    .map(|g| (r.volume * stress * g).norm())
                    .fold(0.0, f64::max)
            })
            .fold(0.0, f64::max)
    }

    /// The inelastic strain in `history` of every element that flows (see
    /// [`Elasticity::law_in_solve`]) brought to the end of the solve with the converged
    /// displacements `u` (m) of the elements `tets`, the strain `offsets` of `history` and
    /// the solve's `creep`: plasticity's return mapping, or the solve's creep. Returns the
    /// largest ‖ε_p‖ afterwards (0 without plasticity or creep).
    pub fn update_inelastic_strain(
        &self,
        (history, offsets): (&mut ElementHistory, &[StrainOffset]),
        tets: &[[usize; 4]],
        u: &[f64],
        creep: Option<&CreepStep>,
    ) -> f64 {
        if !self.inelastic() {
            return 0.0;
        }
        let n = tets.len();
        if history.plastic_strain.len() != n {
            history.plastic_strain = vec![Matrix3::zeros(); n];
        }
        let h = &*history;
        let updated: Vec<Matrix3<f64>> = crate::parallel::map_range(n, |e| {
            let law = self.law_in_solve(h, e, creep);
            let (Some(flow), Some(inelastic)) = (law.flow, h.plastic_strain.get(e)) else {
                return h.plastic_strain[e];
            };
            let elastic = self.elastic_strain(tets, u, e, &offsets[e]);
            match (flow, &self.plasticity) {
                (Flow::Yield(_), Some(plasticity)) => plasticity.return_map(&elastic, inelastic),
                _ => Creep::advance(&law.material, flow, &elastic, inelastic),
            }
        });
        let largest = updated.iter().map(|p| p.norm()).fold(0.0, f64::max);
        history.plastic_strain = updated;
        largest
    }

    /// Elastic strain of element `e` in its own frame with its strain `offset` (see
    /// `fem::ElasticLaw::elastic_strain`).
    pub fn elastic_strain(
        &self,
        tets: &[[usize; 4]],
        u: &[f64],
        e: usize,
        offset: &StrainOffset,
    ) -> Matrix3<f64> {
        let grad_u = self.rest[e].displacement_gradient(&Self::local(u, &tets[e]));
        self.law().elastic_strain(&grad_u, offset).0
    }

    /// Cauchy stress (Pa, Voigt xx yy zz yz xz xy) of every element.
    pub fn stresses(
        &self,
        tets: &[[usize; 4]],
        history: &ElementHistory,
        u: &[f64],
    ) -> Vec<[f64; 6]> {
        let offsets = history.offsets();
        let pressure = self
            .nodal_pressures(tets, history, &offsets, u, None)
            .map(|(p, _)| p);
        crate::parallel::map_range(tets.len(), |e| {
            let mut s = element_stress(
                &self.law_of(history, e),
                &self.rest[e],
                &Self::local(u, &tets[e]),
                &offsets[e],
            );
            // The averaged pressure (the elements' own laws are deviatoric then).
            if let Some(p) = &pressure {
                for v in &mut s[..3] {
                    *v += p[e];
                }
            }
            s
        })
    }

    /// Elastic energy Σ Wₑ (J) at `u`, with the elements' strain `offsets`
    /// (`history.offsets()`) and the creep of the solve `creep`, if any, and each element's
    /// energy written to `element_energy`.
    pub fn energy(
        &self,
        assembly: &Assembly,
        (tets, history, offsets): (&[[usize; 4]], &ElementHistory, &[StrainOffset]),
        (u, creep): (&[f64], Option<&CreepStep>),
        element_energy: &mut [f64],
    ) -> f64 {
        assembly.energies(
            |e, out| {
                let law = self.law_in_solve(history, e, creep);
                self.element_with(tets, &law, u, e, &offsets[e], false, false, out)
            },
            element_energy,
        );
        let volumetric = self
            .nodal_pressures(tets, history, offsets, u, None)
            .map_or(0.0, |(_, energy)| energy);
        // Summed in order so the result does not depend on thread scheduling.
        element_energy.iter().sum::<f64>() + volumetric
    }
}

/// Σ of the element energies, in element order: of `subset`'s elements if given.
fn element_sum(subset: Option<&ElementSubset>, element_energy: &[f64]) -> f64 {
    match subset {
        Some(subset) => subset.sum(element_energy),
        None => element_energy.iter().sum(),
    }
}

/// The elastic energy as a term of a solve: Σ Wₑ assembled element by element in parallel.
pub struct ElasticStep<'a> {
    /// The elasticity.
    pub elasticity: &'a Elasticity,
    /// Element connectivity.
    pub tets: &'a [[usize; 4]],
    /// The elements' history (strain offsets, freeze states).
    pub history: &'a ElementHistory,
    /// Pattern of the free system.
    pub assembly: &'a Assembly,
    /// Per-element energy buffer (J), one per element.
    pub element_energy: &'a mut [f64],
    /// Whether element stiffnesses are projected to be positive semi-definite.
    pub project: bool,
    /// Each element's strain offset, fixed during the solve (`history.offsets()`).
    pub offsets: &'a [StrainOffset],
    /// In a distributed run, the elements this process evaluates and the dofs it owns (all
    /// 3n): the energy, gradient and Hessian are then those of its elements, plus the nodal
    /// volumetric energy and Hessian of its nodes.
    pub subset: Option<(&'a ElementSubset, &'a [bool])>,
    /// The solve's creep, with creep on (none: the elements do not creep in this term).
    pub creep: Option<CreepStep<'a>>,
}

impl<'a> ElasticStep<'a> {
    /// The elastic term of a solve on `tets` with the elements' `history` and its strain
    /// `offsets` (`history.offsets()`, computed once for the solve).
    pub fn new(
        elasticity: &'a Elasticity,
        (tets, history, offsets): (&'a [[usize; 4]], &'a ElementHistory, &'a [StrainOffset]),
        assembly: &'a Assembly,
        element_energy: &'a mut [f64],
        project: bool,
    ) -> Self {
        ElasticStep {
            elasticity,
            tets,
            history,
            assembly,
            element_energy,
            project,
            offsets,
            subset: None,
            creep: None,
        }
    }
}

impl StepTerm for ElasticStep<'_> {
    fn name(&self) -> &'static str {
        "elasticity"
    }

    fn add(
        &mut self,
        u: &[f64],
        energy: &mut f64,
        gradient: Option<&mut [f64]>,
        hessian: Option<&mut [f64]>,
    ) {
        let (el, tets, history, offsets) = (self.elasticity, self.tets, self.history, self.offsets);
        let creep = self.creep.as_ref();
        let (subset, owned) = self.subset.unzip();
        match gradient {
            Some(gradient) => {
                let project = self.project;
                let Some(nodal) = &el.nodal else {
                    self.assembly.assemble_in(
                        subset,
                        |e, with_h, out| {
                            let law = el.law_in_solve(history, e, creep);
                            el.element_with(tets, &law, u, e, &offsets[e], with_h, project, out)
                        },
                        self.element_energy,
                        gradient,
                        hessian,
                    );
                    *energy += element_sum(subset, self.element_energy);
                    return;
                };
                // Nodal volumetric energy: element pressures first, then the elements'
                // deviatoric energy with their pressure's forces and stiffness (its ∂²θ part
                // is indefinite and left out when projecting), then the nodes' Σ Vₐ κₐ ∇θ̄ₐ ∇θ̄ₐᵀ.
                // On a subset, the pressures need every element's volume change; the nodes'
                // energy and Hessian are those of the owned nodes.
                let with_h = hessian.is_some();
                let (change, bulk) =
                    el.volume_changes(tets, history, offsets, u, with_h && !project);
                let theta: Vec<f64> = change.iter().map(|c| c.theta).collect();
                let (pressure, volumetric) = nodal.pressures(&theta, &bulk, &el.rest, tets, owned);
                let mut hessian = hessian;
                self.assembly.assemble_in(
                    subset,
                    |e, with_h, out| {
                        let law = el.law_in_solve(history, e, creep);
                        el.element_with(tets, &law, u, e, &offsets[e], with_h, project, out);
                        change[e].add_pressure(&el.rest[e], pressure[e], out, with_h);
                    },
                    self.element_energy,
                    gradient,
                    hessian.as_deref_mut(),
                );
                if let Some(h) = hessian {
                    nodal.add_hessian(&change, &bulk, &el.rest, h, owned);
                }
                *energy += element_sum(subset, self.element_energy) + volumetric;
            }
            None => match self.subset {
                Some((subset, owned)) => {
                    self.assembly.energies_in(
                        Some(subset),
                        |e, out| {
                            let law = el.law_in_solve(history, e, creep);
                            el.element_with(tets, &law, u, e, &offsets[e], false, false, out)
                        },
                        self.element_energy,
                    );
                    let volumetric = el
                        .nodal_pressures(tets, history, offsets, u, Some(owned))
                        .map_or(0.0, |(_, energy)| energy);
                    *energy += subset.sum(self.element_energy) + volumetric;
                }
                None => {
                    *energy += el.energy(
                        self.assembly,
                        (tets, history, offsets),
                        (u, creep),
                        self.element_energy,
                    );
                }
            },
        }
    }

    fn project_hessian(&mut self, project: bool) -> bool {
        std::mem::replace(&mut self.project, project) != project
    }

    /// A model with a constant tangent (the linear one) with per-element volume and no
    /// plasticity, whose elements' stiffness no freezing blends from step to step: K, whatever
    /// u and the eigenstrain.
    fn hessian_is_fixed(&self) -> bool {
        let e = self.elasticity;
        e.law().constant_tangent()
            && !e.inelastic()
            && e.volumetric() == Volumetric::Element
            && self.history.freeze_state.is_empty()
    }
}
