//! Ice that forms in water (`[freezing] expansion = "displaces_water"`; see
//! docs/ice.md#ice-that-forms-in-water).
//!
//! Water freezing at a front does not strain the ice already there: new ice forms at the
//! water's stress, in the shape the water has, and its 9 % of extra volume pushes the water
//! still liquid around it. Stress builds only where that water cannot go: trapped behind a
//! shell, it is compressed, and the shell around it is pulled apart. (The isotropic expansion
//! of the paper instead grows each element by the ratio in every direction as it freezes; a
//! front crossing the tets of a mesh then freezes neighbours at different times, and their
//! incompatible expansions load the ice with stresses of the order of E e_max, tens to hundreds
//! of MPa, at every resolution.)
//!
//! An element blends water and ice by its freeze state s (`Elasticity::material_of`). When s
//! changes over a solve from s₀ to s₁, before the solve:
//!
//! - **Born at the water's stress** (s₁ > s₀). The element's elastic strain at the solve's
//!   start, ε_e = θ/3 I + ε_e' (θ its volume change), is rescaled so that its stress does not
//!   change with its stiffness: θ K₀/K₁ and ε_e' μ₀/μ₁, K and μ the element's bulk and shear
//!   moduli at s₀ and s₁. Without it, water compressed by p that freezes at a fixed strain
//!   would carry K_ice/K_water ≈ 4 p, and water sheared by the flow (its shear modulus is a
//!   regulariser) would turn its shear strain into ice stress.
//! - **The expansion goes into the water.** The volume the element's ice gains,
//!   ΔV = (s₁ − s₀) V (ratio − 1), is added to the natural volume of the water it touches: the
//!   pocket of connected elements that still hold water (s₁ < 1; connected through shared
//!   nodes) that the element belongs to or borders, shared among several such pockets equally,
//!   and within a pocket spread evenly over its elements of water alone (s₁ = 0) as an
//!   isotropic strain — over all its elements by their water volume (1 − s) V where it has
//!   none: the water of a partly frozen element shares its strain with the element's ice,
//!   which the swelling would load (in a column freezing from one end, with the mean of the
//!   phases' moduli, 10–20 MPa in its ice against 0.4 MPa). Water open to a free surface
//!   swells into it at no cost; trapped water is compressed. An element that borders no water
//!   keeps its expansion itself, isotropically. Melting (s₁ < s₀) takes the volume back the
//!   same way.
//! - **Slush** (`Elasticity::material_of`): a partly frozen element is ice and water in
//!   series, the harmonic means of their moduli, so it carries no shear to speak of until it
//!   is nearly all ice.
//!
//! Both go into the element's inelastic strain (the history's plastic strain), which the offset
//! of every later solve carries; the element's eigenstrain then holds no freezing expansion.
//! Melting changes no stress: the ice's stress falls with its stiffness.

use super::elasticity::Elasticity;
use super::freezing::Freezing;
use super::history::ElementHistory;
use crate::fem::ElasticModel;
use crate::mesh::parts::parts_of;
use nalgebra::Matrix3;

/// Brings the inelastic strains in `after` (the history at a solve's end time, its freeze
/// states and eigenstrains set) to what the ice formed since `before` (the history at the
/// solve's start) was born with and the water's swelling, for the displacements `u` (m) of
/// the solve's start on the elements `tets` of `nodes` nodes, with `freezing`'s expansion.
pub fn form_ice(
    elasticity: &Elasticity,
    freezing: &Freezing,
    (before, after): (&ElementHistory, &mut ElementHistory),
    (tets, nodes, u): (&[[usize; 4]], usize, &[f64]),
) {
    let n = tets.len();
    if after.plastic_strain.len() != n || before.freeze_state.len() != n {
        after.plastic_strain.resize(n, Matrix3::zeros());
        return;
    }
    let born = |e: usize| -> Option<Matrix3<f64>> {
        let (s0, s1) = (before.freeze_state[e], after.freeze_state[e]);
        if s1 <= s0 {
            return None;
        }
        let elastic = elasticity.elastic_strain(tets, u, e, &before.offset_of(e));
        let mean = elastic.trace() / 3.0;
        let deviator = elastic - Matrix3::identity() * mean;
        let moduli = |history: &ElementHistory| {
            let (material, water) = elasticity.material_of(history, e);
            (material.bulk() + water, material.mu)
        };
        let ((k0, mu0), (k1, mu1)) = (moduli(before), moduli(after));
        let born = Matrix3::identity() * (mean * (1.0 - k0 / k1)) + deviator * (1.0 - mu0 / mu1);
        Some(0.5 * (born + born.transpose()))
    };
    let updated: Vec<Option<Matrix3<f64>>> = crate::parallel::map_range(n, born);
    for (strain, change) in after.plastic_strain.iter_mut().zip(updated) {
        if let Some(change) = change {
            *strain += change;
        }
    }
    let added = added_volumes(elasticity, freezing, (before, after), tets, nodes);
    for (e, added) in added.into_iter().enumerate() {
        if added != 0.0 {
            let delta = isotropic_strain(elasticity, after, e, added);
            after.plastic_strain[e] += Matrix3::identity() * delta;
        }
    }
}

/// The isotropic strain δ (dimensionless) that adds `added` (m³) to the natural volume of
/// element `e` of `history`: ΔV/(3V) in the small-strain model, whose volume change is
/// tr ε; in the corotated one, whose natural shape grows by (1 + e)³ for an isotropic offset
/// e, the δ with (1 + e + δ)³ = (1 + e)³ + ΔV/V (the sum of the ΔV/(3V) of the steps would
/// overshoot by 3e², 4 % of the swelling where the last water has taken e = 0.036).
fn isotropic_strain(
    elasticity: &Elasticity,
    history: &ElementHistory,
    e: usize,
    added: f64,
) -> f64 {
    let relative = added / elasticity.rest[e].volume;
    match elasticity.model {
        ElasticModel::Linear => relative / 3.0,
        ElasticModel::Corotated => {
            let grown = 1.0 + history.offset_strain(e).trace() / 3.0;
            (grown.powi(3) + relative).cbrt() - grown
        }
    }
}

/// The natural volume (m³) each element takes from the volume the ice formed between `before`
/// and `after` gains (see the module's documentation).
fn added_volumes(
    elasticity: &Elasticity,
    freezing: &Freezing,
    (before, after): (&ElementHistory, &ElementHistory),
    tets: &[[usize; 4]],
    nodes: usize,
) -> Vec<f64> {
    let n = tets.len();
    let ratio = (1.0 + freezing.expansion).powi(3);
    let volume = |e: usize| elasticity.rest[e].volume;
    let water = |e: usize| 1.0 - after.freeze_state[e];
    let gained: Vec<f64> = (0..n)
        .map(|e| (after.freeze_state[e] - before.freeze_state[e]) * volume(e) * (ratio - 1.0))
        .collect();
    let mut added = vec![0.0; n];
    if gained.iter().all(|g| *g == 0.0) {
        return added;
    }
    // Pockets: the parts of the mesh made of the elements that hold water.
    let wet: Vec<usize> = (0..n).filter(|&e| water(e) > 0.0).collect();
    let wet_tets: Vec<[usize; 4]> = wet.iter().map(|&e| tets[e]).collect();
    let (pocket, count) = parts_of(nodes, &wet_tets);
    let mut wet_node = vec![false; nodes];
    for t in &wet_tets {
        for &v in t {
            wet_node[v] = true;
        }
    }
    let mut into = vec![0.0; count];
    for (e, &g) in gained.iter().enumerate() {
        if g == 0.0 {
            continue;
        }
        let mut touched: Vec<u32> = tets[e]
            .iter()
            .filter(|&&v| wet_node[v])
            .map(|&v| pocket[v])
            .collect();
        touched.sort_unstable();
        touched.dedup();
        if touched.is_empty() {
            // No water around: the element expands in place.
            added[e] += g;
            continue;
        }
        let share = g / touched.len() as f64;
        for p in touched {
            into[p as usize] += share;
        }
    }
    // Within a pocket, the elements of water alone take it where there are any: the water of
    // a partly frozen element shares its strain with the element's ice, which would be loaded.
    let liquid = |e: usize| after.freeze_state[e] == 0.0;
    let mut liquid_volume = vec![0.0; count];
    let mut water_volume = vec![0.0; count];
    for &e in &wet {
        let p = pocket[tets[e][0]] as usize;
        water_volume[p] += water(e) * volume(e);
        if liquid(e) {
            liquid_volume[p] += volume(e);
        }
    }
    for &e in &wet {
        let p = pocket[tets[e][0]] as usize;
        if into[p] == 0.0 {
            continue;
        }
        if liquid_volume[p] > 0.0 {
            if liquid(e) {
                added[e] += into[p] * volume(e) / liquid_volume[p];
            }
        } else {
            added[e] += into[p] * water(e) * volume(e) / water_volume[p];
        }
    }
    added
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fem::Material;
    use crate::mesh::{box_mesh, TetMesh};
    use crate::physics::freezing::{ThermalPoint, Water};

    /// Water (bulk 2.2 GPa, shear 1e-4 of the ice's) on `mesh` that becomes ice of 9 GPa and
    /// expands by `ratio`.
    fn water(mesh: &TetMesh, model: ElasticModel, ratio: f64) -> (Elasticity, Freezing) {
        let ice = Material::from_young_poisson(9e9, 0.33, 917.0);
        let mut elasticity = Elasticity::new(mesh, ice, model);
        elasticity.water_bulk = 2.2e9;
        elasticity.water_shear = 1e-4 * ice.mu;
        elasticity.ice_formation = true;
        let n = mesh.num_tets();
        let at = ThermalPoint {
            time: 0.0,
            fraction: vec![0.0; n],
            temperature: vec![0.5; n],
        };
        let mut freezing = Freezing::thermal(at, ratio, Water::Bulk { modulus: 2.2e9 });
        freezing.displaces_water = true;
        (elasticity, freezing)
    }

    /// The history of `n` elements at freeze states `s`, without expansion.
    fn at_states(s: &[f64]) -> ElementHistory {
        let mut h = ElementHistory::initial(&vec![0.0; s.len()], true);
        h.freeze_state = s.to_vec();
        h
    }

    #[test]
    fn ice_is_born_at_the_stress_of_the_water_it_replaces() {
        // One tet of water compressed by 0.5 % in volume and sheared by 0.2 % freezes
        // (s 0 → 0.4 → 1) at a fixed deformation, without expansion: its stress does not
        // change. The water's pressure is 11 MPa and its shear stress 3.4e5 × 0.2 % = 0.7 kPa;
        // ice at that strain would carry 44 MPa and 6.8 MPa.
        let mesh = TetMesh::from_arrays(
            &[
                [0.0; 3],
                [0.01, 0.0, 0.0],
                [0.0, 0.01, 0.0],
                [0.0, 0.0, 0.01],
            ],
            vec![[0, 1, 2, 3]],
        )
        .unwrap();
        for model in [ElasticModel::Linear, ElasticModel::Corotated] {
            let (elasticity, freezing) = water(&mesh, model, 1.0);
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
                .flat_map(|x| (strain * x).data.0[0])
                .collect();
            let mut history = at_states(&[0.0]);
            let before = elasticity.stresses(&mesh.tets, &history, &u)[0];
            for s in [0.4, 1.0] {
                let mut next = history.clone();
                next.freeze_state = vec![s];
                form_ice(
                    &elasticity,
                    &freezing,
                    (&history, &mut next),
                    (&mesh.tets, 4, &u),
                );
                let now = elasticity.stresses(&mesh.tets, &next, &u)[0];
                // To round-off in the small-strain model; in the corotated one to the first
                // order of its update (as plasticity's), whose error is of the strain times the
                // stress: 5e-3 × 11 MPa ≈ 55 kPa (measured 29 kPa).
                let tolerance = match model {
                    ElasticModel::Linear => 1e-6,
                    ElasticModel::Corotated => 6e4,
                };
                for (a, b) in now.iter().zip(&before) {
                    assert!(
                        (a - b).abs() < tolerance,
                        "{model:?} at s = {s}: {now:?} vs {before:?}"
                    );
                }
                history = next;
            }
            assert!(before[0] < -1e7, "{before:?}");
        }
    }

    #[test]
    fn the_expansion_goes_into_the_water_each_pocket_touches() {
        // A row of 4 cells (24 tets): the first cell's tets freeze (s 0 → 1), the other
        // cells stay water in one pocket, partly frozen in the second cell (s = 0.5). The
        // 9 % the frozen cells gain (and the half of the second cell) swells the pocket's
        // liquid water evenly; the frozen and the partly frozen tets keep none of it, and no
        // volume is lost.
        let mesh = box_mesh([0.0; 3], [0.04, 0.01, 0.01], [4, 1, 1], 6).unwrap();
        let (elasticity, freezing) = water(&mesh, ElasticModel::Linear, 1.09);
        let cell =
            |e: usize| (mesh.tets[e].iter().map(|&v| mesh.rest[v].x).sum::<f64>() / 0.04) as usize;
        let before = at_states(&[0.0; 24]);
        let states: Vec<f64> = (0..24)
            .map(|e| match cell(e) {
                0 => 1.0,
                1 => 0.5,
                _ => 0.0,
            })
            .collect();
        let mut after = at_states(&states);
        let u = vec![0.0; 3 * mesh.num_nodes()];
        form_ice(
            &elasticity,
            &freezing,
            (&before, &mut after),
            (&mesh.tets, mesh.num_nodes(), &u),
        );
        let volume = |e: usize| elasticity.rest[e].volume;
        let gained: f64 = (0..24).map(|e| states[e] * volume(e) * 0.09).sum();
        let swollen: f64 = (0..24)
            .map(|e| after.plastic_strain[e].trace() * volume(e))
            .sum();
        // Σ 3δ V against the gained volume, to round-off.
        assert!(
            (swollen - gained).abs() < 1e-12 * gained,
            "{swollen:e} vs {gained:e}"
        );
        for e in 0..24 {
            let d = after.plastic_strain[e].trace() / 3.0;
            match cell(e) {
                0 => assert_eq!(d, 0.0),
                1 => assert_eq!(d, 0.0),
                _ => assert!(
                    (d - gained / (3.0 * 0.02 * 0.01 * 0.01)).abs() < 1e-15,
                    "{d}"
                ),
            }
        }
        // Every element frozen: the expansion stays where it formed, isotropic.
        let mut frozen = at_states(&[1.0; 24]);
        form_ice(
            &elasticity,
            &freezing,
            (&before, &mut frozen),
            (&mesh.tets, mesh.num_nodes(), &u),
        );
        for e in 0..24 {
            let d = frozen.plastic_strain[e].trace() / 3.0;
            assert!((d - 0.03).abs() < 1e-15, "{d}");
        }
    }
}
