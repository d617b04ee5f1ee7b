//! `[freezing]`: where the front starts (faces of a box, the body's own surface, or the faces
//! touching an obstacle), its speed and the water's model, checked into a [`Freezing`]
//! schedule.

use serde::Deserialize;

use super::regions::SelectionKeys;
use super::{SceneError, Validator};
use crate::mesh::TetMesh;
use crate::physics::freezing::{Freezing, Water};
use crate::physics::{Model, Region};

/// `[freezing]`: a front from the cooling faces of a box (default: the mesh's bounding box).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FreezingSection {
    /// Cooling faces: any of "walls" (±x, ±y), "bottom" (−z), "top" (+z), or single faces
    /// "-x", "+x", "-y", "+y", "-z", "+z". Required unless `[thermal]` drives the freezing.
    pub cooling: Option<Vec<String>>,
    /// Front speed (m/s). Required unless `[thermal]` drives the freezing.
    pub front_speed: Option<f64>,
    /// Time an element takes to freeze once the front reaches it (s). Default 0.
    pub transition_time: Option<f64>,
    /// When the front leaves the cooling faces (s). Default 0.
    pub start_time: Option<f64>,
    /// Volume ratio ice / water. Default 1.09.
    pub expansion_ratio: Option<f64>,
    /// How freezing ice expands: "isotropic" (default, the paper's: each element grows by the
    /// ratio in every direction as it freezes) or "displaces_water" (ice born at the water's
    /// stress, its expansion into the water it touches; see `physics::ice_formation`).
    pub expansion: Option<String>,
    /// "bulk" (default: pressure only, bulk modulus `water_bulk_modulus`) or "inactive".
    pub water: Option<String>,
    /// Bulk modulus of water (Pa). Default 2.2e9.
    pub water_bulk_modulus: Option<f64>,
    /// Regularising shear modulus of unfrozen water (Pa). Default 1e-4 of the ice's μ.
    pub water_shear_modulus: Option<f64>,
    /// Box whose faces cool: lower corner (m). Default: the mesh's bounding box.
    pub min: Option<[f64; 3]>,
    /// Box whose faces cool: upper corner (m).
    pub max: Option<[f64; 3]>,
}

/// The faces of the box `cooling` may name.
pub(super) const BOX_FACES: [&str; 9] =
    ["walls", "bottom", "top", "-x", "+x", "-y", "+y", "-z", "+z"];

/// The box faces (−x, +x, −y, +y, −z, +z) a name of [`BOX_FACES`] stands for.
pub(super) fn box_face_indices(name: &str) -> &'static [usize] {
    match name {
        "walls" => &[0, 1, 2, 3],
        "bottom" | "-z" => &[4],
        "top" | "+z" => &[5],
        "-x" => &[0],
        "+x" => &[1],
        "-y" => &[2],
        "+y" => &[3],
        _ => &[],
    }
}

impl Validator<'_> {
    /// Whether the scene's ice displaces water (`[freezing] expansion = "displaces_water"`)
    /// rather than expanding isotropically (the default).
    pub(super) fn displaces_water(&self, f: &FreezingSection) -> Result<bool, SceneError> {
        match f.expansion.as_deref() {
            None | Some("isotropic") => Ok(false),
            Some("displaces_water") => Ok(true),
            Some(other) => Err(self.invalid(
                "freezing.expansion",
                format!("must be \"isotropic\" or \"displaces_water\", got {other:?}"),
            )),
        }
    }

    /// Whether the mesh files define a physical group `name`.
    pub(super) fn is_group(&self, name: &str) -> bool {
        self.groups.borrow().iter().any(|g| g.name == name)
    }

    /// The boundary faces on the named surfaces `names` (physical surfaces of the mesh file),
    /// for the entry `field`. A name the mesh defines means its group even where it is also a
    /// word (a box face, "surface", "obstacles"); a word the mesh does not define cannot be
    /// mixed with named surfaces.
    pub(super) fn named_faces(
        &self,
        field: &str,
        names: &[String],
        mesh: &TetMesh,
    ) -> Result<Vec<[usize; 3]>, SceneError> {
        let mut selections = Vec::with_capacity(names.len());
        for name in names {
            let known = self.is_group(name);
            let word =
                BOX_FACES.contains(&name.as_str()) || name == "surface" || name == "obstacles";
            if !known && word {
                return Err(self.invalid(
                    field,
                    format!("{name:?} (a box face, \"surface\" or \"obstacles\") and named surfaces of the mesh file cannot be mixed"),
                ));
            }
            if !known {
                return Err(self.invalid(
                    field,
                    format!("unknown face {name:?}: use \"surface\", \"obstacles\", box faces {}, or a physical surface of the mesh file", BOX_FACES.map(|f| format!("{f:?}")).join(", ")),
                ));
            }
            if word {
                self.notices.borrow_mut().push(format!(
                    "{field}: {name:?} is the mesh file's physical surface of that name (a physical group's name wins over the word)"
                ));
            }
            let keys = SelectionKeys {
                min: None,
                max: None,
                region: Some(name),
            };
            selections.push(self.selection(field, keys, Some(2))?);
        }
        let faces: Vec<[usize; 3]> = (self.whole_boundary(mesh).iter())
            .map(|f| f.nodes)
            .filter(|f| {
                let corners = f.map(|i| mesh.rest[i]);
                selections.iter().any(|s| s.contains_face(&corners))
            })
            .collect();
        if self.found_anywhere(faces.len()) == 0 {
            return Err(self.invalid(
                field,
                "the named surfaces hold no boundary face of the mesh",
            ));
        }
        Ok(faces)
    }

    /// The expansion ratio, water model and water shear modulus of `[freezing]` (defaults
    /// without it).
    pub(super) fn water_and_expansion(
        &self,
        f: Option<&FreezingSection>,
        ice: &crate::fem::Material,
    ) -> Result<(f64, Water, f64), SceneError> {
        let ratio = f.and_then(|f| f.expansion_ratio).unwrap_or(1.09);
        if !(ratio > 0.5 && ratio < 2.0) {
            return Err(self.invalid(
                "freezing.expansion_ratio",
                format!("must be in (0.5, 2) (ice/water volume, 1.09 for water), got {ratio}"),
            ));
        }
        let bulk = f.and_then(|f| f.water_bulk_modulus);
        let water = match f.and_then(|f| f.water.as_deref()).unwrap_or("bulk") {
            "bulk" => Water::Bulk {
                modulus: self.positive("freezing.water_bulk_modulus", bulk.unwrap_or(2.2e9))?,
            },
            "inactive" => {
                if bulk.is_some() {
                    return Err(
                        self.invalid("freezing.water_bulk_modulus", "only for water = \"bulk\"")
                    );
                }
                Water::Inactive
            }
            other => {
                return Err(self.invalid(
                    "freezing.water",
                    format!("must be \"bulk\" or \"inactive\", got {other:?}"),
                ))
            }
        };
        let shear = self.non_negative(
            "freezing.water_shear_modulus",
            f.and_then(|f| f.water_shear_modulus)
                .unwrap_or(1e-4 * ice.mu),
        )?;
        Ok((ratio, water, shear))
    }

    /// The prescribed front of `f` on `model` (its mesh, eigenstrains and obstacles), the ice
    /// of material `ice`.
    pub(super) fn freezing(
        &self,
        f: &FreezingSection,
        model: &Model,
        ice: &crate::fem::Material,
    ) -> Result<Freezing, SceneError> {
        let mesh = &model.mesh;
        let eigenstrain = &model.elasticity.eigenstrain;
        let obstacles = model
            .obstacle_contact()
            .map_or(&[][..], |c| &c.obstacles[..]);
        let required = |field: &str| {
            self.invalid(
                field,
                "required: the prescribed front needs `cooling` and `front_speed` (or add [thermal] to freeze by a heat solve)",
            )
        };
        let cooling = f
            .cooling
            .as_ref()
            .ok_or_else(|| required("freezing.cooling"))?;
        let front_speed = f
            .front_speed
            .ok_or_else(|| required("freezing.front_speed"))?;
        let surface = match cooling.as_slice() {
            // A physical surface of the mesh file wins over a word of the same name.
            list if list.iter().any(|n| self.is_group(n)) => {
                Some(self.named_faces("freezing.cooling", list, mesh)?)
            }
            [one] if one == "surface" => Some(
                mesh.boundary_faces()
                    .iter()
                    .map(|f| f.nodes)
                    .collect::<Vec<_>>(),
            ),
            [one] if one == "obstacles" => Some(self.faces_touching(mesh, obstacles)?),
            list if list.iter().any(|n| n == "surface" || n == "obstacles") => {
                return Err(self.invalid(
                    "freezing.cooling",
                    "\"surface\" and \"obstacles\" stand alone, without box faces or each other",
                ))
            }
            list if list.iter().any(|n| !BOX_FACES.contains(&n.as_str())) => {
                Some(self.named_faces("freezing.cooling", list, mesh)?)
            }
            _ => None,
        };
        if surface.is_some() && (f.min.is_some() || f.max.is_some()) {
            return Err(self.invalid(
                "freezing.min",
                "`min`/`max` are the box whose faces cool; not with \"surface\" or \"obstacles\"",
            ));
        }
        let names = cooling;
        let mut cooling = [false; 6];
        for name in names.iter().filter(|_| surface.is_none()) {
            // Names other than box faces were taken as named surfaces above.
            for &k in box_face_indices(name) {
                cooling[k] = true;
            }
        }
        if surface.is_none() && !cooling.contains(&true) {
            return Err(self.invalid("freezing.cooling", "name at least one cooling face"));
        }
        let region = match (f.min, f.max) {
            (None, None) => {
                let (min, max) = self.bounding_box(mesh);
                Region { min, max }
            }
            (Some(min), Some(max)) => self.region("freezing", min, max)?,
            _ => return Err(self.invalid("freezing.min", "give both `min` and `max`, or neither")),
        };
        let speed = self.positive("freezing.front_speed", front_speed)?;
        let transition =
            self.non_negative("freezing.transition_time", f.transition_time.unwrap_or(0.0))?;
        let start = self.non_negative("freezing.start_time", f.start_time.unwrap_or(0.0))?;
        let (ratio, water, water_shear) = self.water_and_expansion(Some(f), ice)?;
        let mut freezing = match &surface {
            Some(triangles) => {
                Freezing::from_surface(mesh, triangles, (speed, start, transition), ratio, water)
            }
            None => Freezing::from_front(
                mesh, &region, cooling, speed, start, transition, ratio, water,
            ),
        };
        freezing.base_eigenstrain = eigenstrain.to_vec();
        freezing.water_shear = water_shear;
        Ok(freezing)
    }
}
