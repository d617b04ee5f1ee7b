//! `[thermal]`: heat conduction with freezing drives the freeze state (instead of a
//! prescribed front): the initial temperatures, surfaces at fixed temperature, convection to
//! the air, and the water and ice properties.

use serde::Deserialize;

use super::freezing::{box_face_indices, FreezingSection, BOX_FACES};
use super::regions::SelectionKeys;
use super::{SceneError, Validator};
use crate::mesh::TetMesh;
use crate::physics::freezing::{Freezing, ThermalPoint};
use crate::physics::thermal_strain::{Expansion, ThermalStrain};
use crate::thermal::link::element_means;
use crate::thermal::{HeatBoundary, Phase, Phases};

/// `[thermal]`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ThermalSection {
    /// Initial temperature everywhere (°C), unless a `[[thermal.initial]]` box or region says
    /// otherwise.
    pub initial_temperature: f64,
    /// Boxes or named volumes with their own initial temperature.
    #[serde(default)]
    pub initial: Vec<InitialTemperature>,
    /// Surfaces held at a temperature.
    #[serde(default)]
    pub fixed: Vec<FixedTemperature>,
    /// Surfaces exchanging heat with the air or a container wall.
    #[serde(default)]
    pub convection: Vec<Convection>,
    /// Ice conductivity (W/(m K)). Default 2.22.
    pub ice_conductivity: Option<f64>,
    /// Ice specific heat (J/(kg K)). Default 2050.
    pub ice_heat_capacity: Option<f64>,
    /// Water conductivity (W/(m K)). Default 0.561.
    pub water_conductivity: Option<f64>,
    /// Water specific heat (J/(kg K)). Default 4217.
    pub water_heat_capacity: Option<f64>,
    /// Latent heat of fusion (J/kg). Default 334e3.
    pub latent_heat: Option<f64>,
    /// Melting point (°C). Default 0.
    pub melting_point: Option<f64>,
    /// Width of the temperature range the latent heat is released over (K). Default 0.1.
    pub mushy_range: Option<f64>,
}

/// `[[thermal.initial]]`: a box (`min`, `max`) or named volume (`region`) and its initial
/// temperature (°C).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InitialTemperature {
    pub min: Option<[f64; 3]>,
    pub max: Option<[f64; 3]>,
    pub region: Option<String>,
    pub temperature: f64,
}

/// `[[thermal.fixed]]`: boundary faces (box faces of the mesh's bounding box, "surface", or
/// named surfaces of the mesh file) held at `temperature` (°C).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FixedTemperature {
    pub faces: Vec<String>,
    pub temperature: f64,
}

/// `[[thermal.convection]]`: boundary faces exchanging heat h (T − T_ambient) with their
/// surroundings: air, or a container wall through the contact's conductance.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Convection {
    pub faces: Vec<String>,
    /// Heat transfer coefficient (W/(m² K)).
    pub h: f64,
    /// Temperature of the surroundings (°C).
    pub ambient_temperature: f64,
}

/// The validated heat model of a scene, built on its mesh when the run starts.
#[derive(Clone, Debug, PartialEq)]
pub struct HeatSetup {
    /// Water and ice.
    pub phases: Phases,
    /// Fixed temperatures and convection.
    pub boundary: HeatBoundary,
    /// Initial temperature per node (°C).
    pub initial: Vec<f64>,
    /// Lumped mass per node (kg): the model's, and at the nodes of a process's part it does
    /// not own (whose mass the model leaves out, see `Scene::part`) the owner's.
    pub mass: Vec<f64>,
}

/// Temperatures below absolute zero are not temperatures (°C).
const ABSOLUTE_ZERO: f64 = -273.15;

impl Validator<'_> {
    /// The boundary faces `names` stand for, for the entry `field`: box faces of the mesh's
    /// bounding box, "surface" (every boundary face), or named surfaces of the mesh file.
    fn thermal_faces(
        &self,
        field: &str,
        names: &[String],
        mesh: &TetMesh,
    ) -> Result<Vec<[usize; 3]>, SceneError> {
        let boundary: Vec<[usize; 3]> = (self.whole_boundary(mesh).iter())
            .map(|f| f.nodes)
            .collect();
        match names {
            [] => Err(self.invalid(field, "name at least one face")),
            // A physical surface of the mesh file wins over a word of the same name.
            list if list.iter().any(|n| self.is_group(n)) => self.named_faces(field, list, mesh),
            [one] if one == "surface" => Ok(boundary),
            list if list.iter().all(|n| BOX_FACES.contains(&n.as_str())) => {
                let (lo, hi) = self.bounding_box(mesh);
                let tolerance = 1e-9 * (hi - lo).norm();
                let mut on = [false; 6];
                for name in list {
                    for &k in box_face_indices(name) {
                        on[k] = true;
                    }
                }
                let faces: Vec<[usize; 3]> = boundary
                    .into_iter()
                    .filter(|f| {
                        (0..6).any(|k| {
                            let (axis, value) =
                                (k / 2, if k % 2 == 0 { lo[k / 2] } else { hi[k / 2] });
                            on[k]
                                && f.iter()
                                    .all(|&i| (mesh.rest[i][axis] - value).abs() <= tolerance)
                        })
                    })
                    .collect();
                if self.found_anywhere(faces.len()) == 0 {
                    return Err(self.invalid(
                        field,
                        "no boundary face lies on those faces of the mesh's bounding box",
                    ));
                }
                Ok(faces)
            }
            list => self.named_faces(field, list, mesh),
        }
    }

    fn temperature(&self, field: &str, t: f64) -> Result<f64, SceneError> {
        if t.is_finite() && t > ABSOLUTE_ZERO {
            Ok(t)
        } else {
            Err(self.invalid(
                field,
                format!("must be a temperature above −273.15 °C, got {t}"),
            ))
        }
    }

    /// The heat model of `[thermal]` on `mesh`, whose nodes' lumped masses are `mass`.
    pub(super) fn thermal(
        &self,
        t: &ThermalSection,
        (mesh, mass): (&TetMesh, &[f64]),
    ) -> Result<HeatSetup, SceneError> {
        let d = Phases::WATER_ICE;
        let positive = |field: &str, v: Option<f64>, default: f64| {
            self.positive(&format!("thermal.{field}"), v.unwrap_or(default))
        };
        let phases = Phases {
            ice: Phase {
                conductivity: positive("ice_conductivity", t.ice_conductivity, d.ice.conductivity)?,
                heat_capacity: positive(
                    "ice_heat_capacity",
                    t.ice_heat_capacity,
                    d.ice.heat_capacity,
                )?,
            },
            water: Phase {
                conductivity: positive(
                    "water_conductivity",
                    t.water_conductivity,
                    d.water.conductivity,
                )?,
                heat_capacity: positive(
                    "water_heat_capacity",
                    t.water_heat_capacity,
                    d.water.heat_capacity,
                )?,
            },
            latent_heat: self.non_negative(
                "thermal.latent_heat",
                t.latent_heat.unwrap_or(d.latent_heat),
            )?,
            melting_point: self.temperature(
                "thermal.melting_point",
                t.melting_point.unwrap_or(d.melting_point),
            )?,
            mushy_range: positive("mushy_range", t.mushy_range, d.mushy_range)?,
        };
        let mut initial =
            vec![
                self.temperature("thermal.initial_temperature", t.initial_temperature)?;
                mesh.num_nodes()
            ];
        for (k, entry) in t.initial.iter().enumerate() {
            let field = format!("thermal.initial[{k}]");
            let value = self.temperature(&format!("{field}.temperature"), entry.temperature)?;
            let keys = SelectionKeys {
                min: entry.min,
                max: entry.max,
                region: entry.region.as_ref(),
            };
            let selection = self.selection(&field, keys, Some(3))?;
            let mut found = 0;
            for (i, x) in mesh.rest.iter().enumerate() {
                if selection.contains_node(x) {
                    initial[i] = value;
                    found += 1;
                }
            }
            if self.found_anywhere(found) == 0 {
                return Err(self.invalid(&field, "holds no node of the mesh"));
            }
        }
        let mut boundary = HeatBoundary::default();
        for (k, entry) in t.fixed.iter().enumerate() {
            let field = format!("thermal.fixed[{k}]");
            let value = self.temperature(&format!("{field}.temperature"), entry.temperature)?;
            let mut nodes: Vec<usize> = self
                .thermal_faces(&format!("{field}.faces"), &entry.faces, mesh)?
                .into_iter()
                .flatten()
                .collect();
            nodes.sort_unstable();
            nodes.dedup();
            boundary.fixed.extend(nodes.into_iter().map(|i| (i, value)));
        }
        // On a part, a node it does not own may lie on a fixed face only its owner holds: the
        // owners' fixed temperatures and whole masses, at every node.
        let mut held = vec![0.0; 3 * mesh.num_nodes()];
        for (i, &m) in mass.iter().enumerate() {
            held[3 * i] = m;
        }
        for &(i, t) in &boundary.fixed {
            held[3 * i + 1..3 * i + 3].copy_from_slice(&[1.0, t]);
        }
        if self.copy_from_owners(&mut held) {
            boundary.fixed = (0..mesh.num_nodes())
                .filter(|&i| held[3 * i + 1] == 1.0)
                .map(|i| (i, held[3 * i + 2]))
                .collect();
        }
        for (k, entry) in t.convection.iter().enumerate() {
            let field = format!("thermal.convection[{k}]");
            let h = self.non_negative(&format!("{field}.h"), entry.h)?;
            let air = self.temperature(
                &format!("{field}.ambient_temperature"),
                entry.ambient_temperature,
            )?;
            let faces = self.thermal_faces(&format!("{field}.faces"), &entry.faces, mesh)?;
            boundary
                .convection
                .extend(faces.into_iter().map(|f| (f, h, air)));
        }
        Ok(HeatSetup {
            phases,
            boundary,
            initial,
            mass: held.iter().step_by(3).copied().collect(),
        })
    }

    /// The freezing schedule a heat model drives: `[freezing]`'s expansion and water model
    /// (its front keys are refused: the heat solve places the front), starting from the
    /// initial temperatures' ice fractions.
    pub(super) fn thermal_freezing(
        &self,
        f: Option<&FreezingSection>,
        setup: &HeatSetup,
        (mesh, eigenstrain): (&TetMesh, &[f64]),
        ice: &crate::fem::Material,
        expansion: Option<Expansion>,
    ) -> Result<Freezing, SceneError> {
        if let Some(f) = f {
            let front = [
                ("cooling", f.cooling.is_some()),
                ("front_speed", f.front_speed.is_some()),
                ("transition_time", f.transition_time.is_some()),
                ("start_time", f.start_time.is_some()),
                ("min", f.min.is_some() || f.max.is_some()),
            ];
            if let Some((key, _)) = front.iter().find(|(_, set)| *set) {
                return Err(self.invalid(
                    &format!("freezing.{key}"),
                    "with [thermal] the heat solve places the front: remove the prescribed front's keys (cooling, front_speed, transition_time, start_time, min/max)",
                ));
            }
        }
        let (ratio, water, shear) = self.water_and_expansion(f, ice)?;
        let mut fixed = setup.initial.clone();
        for &(i, t) in &setup.boundary.fixed {
            fixed[i] = t;
        }
        // As `HeatLink::element_states`: means over the nodes.
        let nodal: Vec<f64> = fixed
            .iter()
            .map(|&t| setup.phases.ice_fraction(t))
            .collect();
        let at = ThermalPoint {
            time: 0.0,
            fraction: element_means(&nodal, &mesh.tets),
            temperature: element_means(&fixed, &mesh.tets),
        };
        let thermal_strain = expansion.map(|expansion| {
            let melting = setup.phases.melting_point;
            ThermalStrain::new(expansion, &at.fraction, &at.temperature, melting)
        });
        let mut freezing = Freezing::thermal(at, ratio, water);
        freezing.base_eigenstrain = eigenstrain.to_vec();
        freezing.water_shear = shear;
        freezing.thermal_strain = thermal_strain;
        Ok(freezing)
    }
}
