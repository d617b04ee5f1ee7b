//! `[material]` and `[materials.NAME]`: the elastic constants, and which elements (by body or
//! region) are of which material.

use super::regions::SelectionKeys;
use super::{SceneError, SceneFile, Validator};
use crate::fem::{ElasticModel, Material};
use crate::mesh::TetMesh;
use crate::physics::elasticity::Volumetric;
use crate::physics::thermal_strain::Expansion;
use crate::physics::Elasticity;
use serde::Deserialize;

/// `[material]`, and `[materials.NAME]`: a material other than `[material]` (which sets the
/// strain measure and volumetric discretisation for all), for the `[[body]]` entries that name
/// it and for the elements of `region` or of the box `min`–`max` (these override bodies').
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialSection {
    /// ρ (kg/m³).
    pub density: f64,
    /// λ (Pa); give with `mu`.
    pub lambda: Option<f64>,
    /// μ (Pa); give with `lambda`.
    pub mu: Option<f64>,
    /// E (Pa); give with `poisson_ratio`.
    pub youngs_modulus: Option<f64>,
    /// ν; give with `youngs_modulus`.
    pub poisson_ratio: Option<f64>,
    /// Strain measure, default corotated.
    pub model: Option<ElasticModel>,
    /// Volumetric discretisation, `"element"` (default) or `"nodal"` (average nodal
    /// pressure: no volumetric locking).
    pub volumetric: Option<Volumetric>,
    /// `[materials.NAME]` only: a named physical volume of the mesh file whose elements are of
    /// this material.
    pub region: Option<String>,
    /// `[materials.NAME]` only: box lower corner (m); elements whose centroid is in the box
    /// are of this material.
    pub min: Option<[f64; 3]>,
    /// `[materials.NAME]` only: box upper corner (m).
    pub max: Option<[f64; 3]>,
    /// `[material]` with `[thermal]` only: the ice's linear thermal expansion coefficient
    /// (1/K), a number or a table of [temperature °C, coefficient 1/K] rows.
    pub thermal_expansion: Option<ThermalExpansionKey>,
}

/// `thermal_expansion`: one coefficient (1/K), or [temperature °C, coefficient 1/K] rows.
#[derive(Debug, Deserialize)]
#[serde(untagged)]
pub enum ThermalExpansionKey {
    /// One coefficient at every temperature.
    Constant(f64),
    /// Rows with increasing temperatures, linear between them, constant beyond.
    Table(Vec<[f64; 2]>),
}

/// Largest |α| accepted (1/K): solids' coefficients are 1e-6 … 3e-4 (ice ≈ 5e-5).
const MAX_EXPANSION: f64 = 1e-3;

impl Validator<'_> {
    pub(super) fn material(
        &self,
        m: &MaterialSection,
    ) -> Result<(Material, ElasticModel), SceneError> {
        let only_named = [
            ("region", m.region.is_some()),
            ("min", m.min.is_some()),
            ("max", m.max.is_some()),
        ];
        if let Some((key, _)) = only_named.iter().find(|(_, given)| *given) {
            return Err(self.invalid(
                &format!("material.{key}"),
                "[material] holds every element no other claims; regions belong to [materials.NAME] entries",
            ));
        }
        let material = self.constants(
            "material",
            m.density,
            [m.lambda, m.mu, m.youngs_modulus, m.poisson_ratio],
        )?;
        Ok((material, m.model.unwrap_or(ElasticModel::Corotated)))
    }

    /// `[material] thermal_expansion`, checked: |α| ≤ [`MAX_EXPANSION`], a table's
    /// temperatures finite and increasing.
    pub(super) fn thermal_expansion(
        &self,
        key: &ThermalExpansionKey,
    ) -> Result<Expansion, SceneError> {
        let field = "material.thermal_expansion";
        let coefficient = |f: &str, a: f64| {
            if a.is_finite() && a.abs() <= MAX_EXPANSION {
                Ok(a)
            } else {
                Err(self.invalid(f, format!("must be a coefficient in 1/K with |α| ≤ {MAX_EXPANSION:e} (ice: about 5e-5), got {a}")))
            }
        };
        match key {
            ThermalExpansionKey::Constant(a) => Ok(Expansion::Constant(coefficient(field, *a)?)),
            ThermalExpansionKey::Table(rows) => {
                if rows.len() < 2 {
                    return Err(self.invalid(field, "a table needs at least two [temperature °C, coefficient 1/K] rows (or give one number)"));
                }
                let mut points = Vec::with_capacity(rows.len());
                for (i, &[t, a]) in rows.iter().enumerate() {
                    let row = format!("{field}[{i}]");
                    let t = self.finite(&row, t)?;
                    let previous: Option<&(f64, f64)> = points.last();
                    if let Some(&(last, _)) = previous.filter(|&&(last, _)| t <= last) {
                        return Err(self.invalid(
                            &row,
                            format!(
                                "temperatures must increase row by row, got {t} °C after {last} °C"
                            ),
                        ));
                    }
                    points.push((t, coefficient(&row, a)?));
                }
                Ok(Expansion::Table(points))
            }
        }
    }

    /// A material from its density and `[lambda, mu, youngs_modulus, poisson_ratio]` (one
    /// pair given), the fields named under `field`.
    fn constants(
        &self,
        field: &str,
        density: f64,
        pairs: [Option<f64>; 4],
    ) -> Result<Material, SceneError> {
        let f = |name: &str| format!("{field}.{name}");
        let density = self.positive(&f("density"), density)?;
        Ok(match pairs {
            [Some(lambda), Some(mu), None, None] => {
                let lambda = self.finite(&f("lambda"), lambda)?;
                let mu = self.positive(&f("mu"), mu)?;
                // Positive bulk modulus ⇔ ν in (−1, 0.5); ν < 0.5 strictly (no incompressibility).
                if lambda + 2.0 * mu / 3.0 <= 0.0 {
                    return Err(self.invalid(&f("lambda"), format!("must be > −2μ/3 = {:e} Pa (positive bulk modulus), got {lambda:e}", -2.0 * mu / 3.0)));
                }
                Material { lambda, mu, density }
            }
            [None, None, Some(e), Some(nu)] => {
                let e = self.positive(&f("youngs_modulus"), e)?;
                if !(nu.is_finite() && nu > -1.0 && nu < 0.5) {
                    return Err(self.invalid(&f("poisson_ratio"), format!("must be in (−1, 0.5), got {nu}")));
                }
                Material::from_young_poisson(e, nu, density)
            }
            _ => {
                return Err(self.invalid(
                    field,
                    "give either `lambda` and `mu`, or `youngs_modulus` and `poisson_ratio` (exactly one pair)",
                ))
            }
        })
    }

    /// The `[materials.NAME]` entries into `elasticity`: bodies that name one are made of
    /// it, then the elements of each entry's region (overriding bodies').
    pub(super) fn other_materials(
        &self,
        raw: &SceneFile,
        mesh: &TetMesh,
        bodies: &[std::ops::Range<usize>],
        elasticity: &mut Elasticity,
    ) -> Result<(), SceneError> {
        let names: Vec<&String> = raw.materials.keys().collect();
        if names.len() >= u16::MAX as usize {
            return Err(self.invalid("materials", format!("at most {} entries", u16::MAX - 1)));
        }
        let mut index = vec![0u16; mesh.num_tets()];
        let mut used = vec![false; names.len()];
        for (b, body) in raw.body.iter().enumerate() {
            let Some(name) = &body.material else { continue };
            let k = names.iter().position(|n| *n == name).ok_or_else(|| {
                self.invalid(
                    &format!("body[{b}].material"),
                    format!(
                        "no [materials.{name}] entry (the scene's materials: {})",
                        if names.is_empty() {
                            "none".to_string()
                        } else {
                            names
                                .iter()
                                .map(|n| format!("{n:?}"))
                                .collect::<Vec<_>>()
                                .join(", ")
                        }
                    ),
                )
            })?;
            index[bodies[b].clone()].fill(k as u16 + 1);
            used[k] = true;
        }
        for (k, (name, m)) in raw.materials.iter().enumerate() {
            let field = format!("materials.{name}");
            if m.thermal_expansion.is_some() {
                return Err(self.invalid(
                    &format!("{field}.thermal_expansion"),
                    "thermal strain is defined for the `[material]` ice of a scene with [thermal] only",
                ));
            }
            if m.model.is_some() || m.volumetric.is_some() {
                let key = if m.model.is_some() {
                    "model"
                } else {
                    "volumetric"
                };
                return Err(self.invalid(
                    &format!("{field}.{key}"),
                    "is set for all materials by [material]",
                ));
            }
            let material = self.constants(
                &field,
                m.density,
                [m.lambda, m.mu, m.youngs_modulus, m.poisson_ratio],
            )?;
            elasticity.other_materials.push(material);
            if m.min.is_none() && m.max.is_none() && m.region.is_none() {
                if !used[k] {
                    return Err(self.invalid(
                        &field,
                        "is used nowhere: give it a `region` (or `min`/`max`), or name it in a [[body]]'s `material`",
                    ));
                }
                continue;
            }
            let keys = SelectionKeys {
                min: m.min,
                max: m.max,
                region: m.region.as_ref(),
            };
            let region = self.selection(&field, keys, Some(3))?;
            for t in self.selected_elements(&field, mesh, &region)? {
                index[t] = k as u16 + 1;
            }
        }
        if index.iter().any(|&k| k > 0) {
            elasticity.material_index = index;
        }
        Ok(())
    }
}
