//! Ice that grows from water (`[freezing] expansion = "growth"`; see docs/ice.md#ice-that-grows).
//!
//! Water freezing at a front does not strain the ice already there: new ice forms at the
//! water's pressure, in the shape the water has, and its 9 % of extra volume pushes the water
//! ahead of it along the direction the ice grows. Stress builds only where that water cannot
//! go: trapped behind a shell, it is compressed, and the shell around it is pulled apart.
//!
//! An element blends water and ice by its freeze state s (`Elasticity::material_of`). When s
//! rises over a solve from s₀ to s₁, before the solve:
//!
//! - **Born at the water's stress.** The element's elastic strain at the solve's start,
//!   ε_e = θ/3 I + ε_e' (θ its volume change), is rescaled so that its stress does not change
//!   with its stiffness: θ K₀/K₁ and ε_e' μ₀/μ₁, K and μ the element's bulk and shear moduli
//!   at s₀ and s₁. Without it, water compressed by p that freezes at a fixed strain would carry
//!   K_ice/K_water ≈ 4 p, and water sheared by the flow (its shear modulus is a regulariser)
//!   would turn its shear strain into ice stress.
//! - **Grown along the temperature gradient.** The expansion e = e_max (s − s_i) in every
//!   direction (the element's eigenstrain, as for the isotropic expansion; s_i the ice it
//!   started with) is redirected along the unit temperature gradient n of the element (the
//!   direction of the heat flow, along which ice grows) by a deviatoric 3 Δg (n⊗n − I/3): the
//!   same volume, all of it along n, so a layer freezing on a wall thickens without growing
//!   along the wall. Δg is what makes the natural shape's stretch across n exactly 1 in the
//!   element's strain measure: Δg = e₁ − e₀ in the small-strain model (ε* = e I + d), and
//!   Δg = ln((1 + e₁)/(1 + e₀)) in the corotated one (F* = (1 + e) exp(d); with e₁ − e₀ there,
//!   a fully grown element would shrink across n by e²/2, 4e-4, a stress of 5 MPa). Where the
//!   temperature is uniform the growth stays isotropic.
//!
//! Both go into the element's inelastic strain (the history's plastic strain), which the offset
//! of every later solve carries. Melting (s falling) changes neither: the ice's stress falls
//! with its stiffness, and the isotropic part of its expansion is given back.

use super::elasticity::Elasticity;
use super::freezing::Freezing;
use super::history::ElementHistory;
use crate::fem::ElasticModel;
use nalgebra::{Matrix3, Vector3};

/// Brings the inelastic strains in `after` (the history at a solve's end time, its freeze
/// states and eigenstrains set) to what the ice formed since `before` (the history at the
/// solve's start) was born with, for the displacements `u` (m) of the solve's start, the
/// elements `tets` and the nodal temperatures `temperature` (°C) of the solve's end, with the
/// expansion and initial ice of `freezing`.
pub fn form_ice(
    elasticity: &Elasticity,
    freezing: &Freezing,
    (before, after): (&ElementHistory, &mut ElementHistory),
    (tets, u): (&[[usize; 4]], &[f64]),
    temperature: &[f64],
) {
    let n = tets.len();
    if after.plastic_strain.len() != n {
        after.plastic_strain = vec![Matrix3::zeros(); n];
    }
    let formed = |e: usize| -> Option<Matrix3<f64>> {
        let (s0, s1) = (*before.freeze_state.get(e)?, after.freeze_state[e]);
        if s1 <= s0 {
            return None;
        }
        let elastic = elasticity.elastic_strain(tets, u, e, &before.offset_of(e));
        let mean = elastic.trace() / 3.0;
        let deviator = elastic - Matrix3::identity() * mean;
        let (k0, k1) = (elasticity.bulk_of(before, e), elasticity.bulk_of(after, e));
        let (mu0, mu1) = (
            elasticity.material_of(before, e).0.mu,
            elasticity.material_of(after, e).0.mu,
        );
        let mut born =
            Matrix3::identity() * (mean * (1.0 - k0 / k1)) + deviator * (1.0 - mu0 / mu1);
        if let Some(direction) = growth_direction(elasticity, tets, e, temperature) {
            let initial = freezing.initial_ice.get(e).copied().unwrap_or(0.0);
            let [e0, e1] = [s0, s1].map(|s| (s - initial) * freezing.expansion);
            let grown = match elasticity.model {
                ElasticModel::Linear => e1 - e0,
                ElasticModel::Corotated => ((1.0 + e1) / (1.0 + e0)).ln(),
            };
            let along = direction * direction.transpose() - Matrix3::identity() / 3.0;
            born += along * (3.0 * grown);
        }
        Some(after.plastic_strain[e] + 0.5 * (born + born.transpose()))
    };
    let updated: Vec<Option<Matrix3<f64>>> = crate::parallel::map_range(n, formed);
    for (strain, new) in after.plastic_strain.iter_mut().zip(updated) {
        if let Some(new) = new {
            *strain = new;
        }
    }
}

/// The unit temperature gradient of element `e` (in rest coordinates) from the nodal
/// `temperature` (°C), none where the temperature is uniform over it.
fn growth_direction(
    elasticity: &Elasticity,
    tets: &[[usize; 4]],
    e: usize,
    temperature: &[f64],
) -> Option<Vector3<f64>> {
    let mut gradient = Vector3::zeros();
    for (&i, g) in tets[e].iter().zip(&elasticity.rest[e].grads) {
        gradient += g * *temperature.get(i)?;
    }
    let norm = gradient.norm();
    (norm > 0.0).then(|| gradient / norm)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fem::Material;
    use crate::mesh::TetMesh;
    use crate::physics::freezing::{ThermalPoint, Water};
    use nalgebra::Vector3;

    /// One tet of water (bulk 2.2 GPa, shear 1e-4 of the ice's) becoming ice of 9 GPa.
    fn one_tet(model: ElasticModel) -> (TetMesh, Elasticity, Freezing) {
        let nodes = [
            Vector3::new(0.0, 0.0, 0.0),
            Vector3::new(0.01, 0.0, 0.0),
            Vector3::new(0.0, 0.01, 0.0),
            Vector3::new(0.0, 0.0, 0.01),
        ];
        let mesh = TetMesh::new(nodes.to_vec(), vec![[0, 1, 2, 3]]).unwrap();
        let ice = Material::from_young_poisson(9e9, 0.33, 917.0);
        let mut elasticity = Elasticity::new(&mesh, ice, model);
        elasticity.water_bulk = 2.2e9;
        elasticity.water_shear = 1e-4 * ice.mu;
        elasticity.ice_growth = true;
        let at = ThermalPoint {
            time: 0.0,
            fraction: vec![0.0],
            temperature: vec![0.5],
        };
        let freezing = Freezing::thermal(at, 1.09, Water::Bulk { modulus: 2.2e9 });
        (mesh, elasticity, freezing)
    }

    /// The history of the tet at freeze state `s`, without expansion.
    fn at_state(s: f64) -> ElementHistory {
        let mut h = ElementHistory::initial(&[0.0], true);
        h.freeze_state = vec![s];
        h
    }

    #[test]
    fn ice_is_born_at_the_stress_of_the_water_it_replaces() {
        // Water compressed by 0.5 % in volume and sheared by 0.2 % freezes (s 0 → 0.4 → 1)
        // at a fixed deformation: its stress does not change (the expansion is left out
        // here). The water's pressure is 11 MPa and its shear stress 3.4e5 × 0.2 % = 0.7 kPa;
        // ice at that strain would carry 44 MPa and 6.8 MPa.
        for model in [ElasticModel::Linear, ElasticModel::Corotated] {
            let (mesh, elasticity, freezing) = one_tet(model);
            let strain = Matrix3::new(
                -1.0 / 600.0,
                0.001,
                0.0,
                0.001,
                -1.0 / 600.0,
                0.0,
                0.0,
                0.0,
                -1.0 / 600.0,
            );
            let u: Vec<f64> = mesh
                .rest
                .iter()
                .flat_map(|x| (strain * x).iter().copied().collect::<Vec<_>>())
                .collect();
            let uniform = vec![0.0; 4];
            let mut history = at_state(0.0);
            let water = elasticity.stresses(&mesh.tets, &history, &u)[0];
            for s in [0.4, 1.0] {
                let mut next = history.clone();
                next.freeze_state = vec![s];
                form_ice(
                    &elasticity,
                    &freezing,
                    (&history, &mut next),
                    (&mesh.tets, &u),
                    &uniform,
                );
                let now = elasticity.stresses(&mesh.tets, &next, &u)[0];
                // To round-off in the small-strain model; in the corotated one to the first
                // order of its update (as plasticity's), whose error is of the strain times the
                // stress: 5e-3 × 11 MPa ≈ 55 kPa (measured 29 kPa).
                let tolerance = match model {
                    ElasticModel::Linear => 1e-6,
                    ElasticModel::Corotated => 6e4,
                };
                for (a, b) in now.iter().zip(&water) {
                    assert!(
                        (a - b).abs() < tolerance,
                        "{model:?} at s = {s}: {now:?} vs {water:?}"
                    );
                }
                history = next;
            }
            assert!(water[0] < -1e7, "{water:?}");
        }
    }

    #[test]
    fn ice_grows_along_the_temperature_gradient() {
        // Temperatures falling along x: the expansion of ice formed from s = 0 to 1 goes
        // along x alone. A tet free to grow along x and held across it is then stress-free:
        // its natural shape is stretched by exactly 1.09 along x and by 1 across.
        for model in [ElasticModel::Linear, ElasticModel::Corotated] {
            let (mesh, elasticity, freezing) = one_tet(model);
            let temperature: Vec<f64> = mesh.rest.iter().map(|x| -1.0 + 100.0 * x.x).collect();
            let before = at_state(0.0);
            let mut after = at_state(1.0);
            after.eigenstrain = vec![freezing.expansion];
            let zero = vec![0.0; 12];
            form_ice(
                &elasticity,
                &freezing,
                (&before, &mut after),
                (&mesh.tets, &zero),
                &temperature,
            );
            let stretch = match model {
                ElasticModel::Linear => 3.0 * freezing.expansion,
                ElasticModel::Corotated => 0.09,
            };
            let u: Vec<f64> = mesh
                .rest
                .iter()
                .flat_map(|x| [stretch * x.x, 0.0, 0.0])
                .collect();
            let stress = elasticity.stresses(&mesh.tets, &after, &u)[0];
            // Against the 390 MPa the isotropic expansion would carry across x: round-off of
            // strains of 0.09 (measured 0 and 3.4e-6 Pa).
            for s in stress {
                assert!(s.abs() < 1e-2, "{model:?}: {stress:?}");
            }
        }
    }
}
