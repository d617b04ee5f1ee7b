//! Where scene entries apply: a box of rest coordinates or a named physical group of the
//! mesh file.

use super::{SceneError, Validator};
use crate::mesh::TetMesh;
use crate::physics::Selection;

/// An entry's keys that say where it applies, as written: a box `min`–`max` (m) or the name
/// of a physical group, `region`.
#[derive(Clone, Copy)]
pub(super) struct SelectionKeys<'a> {
    pub min: Option<[f64; 3]>,
    pub max: Option<[f64; 3]>,
    pub region: Option<&'a String>,
}

impl Validator<'_> {
    /// Where an entry applies: the box `min`–`max` or the named group `region` (of dimension
    /// `dim`: 2 surfaces, 3 volumes; `None`: either).
    pub(super) fn selection(
        &self,
        field: &str,
        keys: SelectionKeys,
        dim: Option<u8>,
    ) -> Result<Selection, SceneError> {
        match (keys.min, keys.max, keys.region) {
            (Some(min), Some(max), None) => Ok(Selection::Box(self.region(field, min, max)?)),
            (None, None, Some(name)) => {
                let groups = self.groups.borrow();
                let listing = || {
                    let names: Vec<String> = groups
                        .iter()
                        .map(|g| format!("{:?} ({})", g.name, kind_name(g.dim)))
                        .collect();
                    if names.is_empty() {
                        "the mesh has no named physical groups".to_string()
                    } else {
                        format!("the mesh's groups: {}", names.join(", "))
                    }
                };
                let group = groups.iter().find(|g| &g.name == name).ok_or_else(|| {
                    self.invalid(
                        &format!("{field}.region"),
                        format!("no physical group {name:?}; {}", listing()),
                    )
                })?;
                match dim {
                    Some(d) if d != group.dim => Err(self.invalid(
                        &format!("{field}.region"),
                        format!(
                            "{name:?} is a {}; this entry needs a {}",
                            kind_name(group.dim),
                            kind_name(d)
                        ),
                    )),
                    _ => Ok(Selection::Group(group.clone())),
                }
            }
            (_, _, Some(_)) => Err(self.invalid(
                &format!("{field}.region"),
                "give a named `region` or a box `min`/`max`, not both",
            )),
            _ => Err(self.invalid(
                field,
                "give a box (`min` and `max`, m) or a named `region` (a physical group of the mesh file)",
            )),
        }
    }

    /// The elements of `mesh` `region` selects (at least one in the whole mesh, else an error
    /// naming `field`).
    pub(super) fn selected_elements(
        &self,
        field: &str,
        mesh: &TetMesh,
        region: &Selection,
    ) -> Result<Vec<usize>, SceneError> {
        let selected: Vec<usize> = (0..mesh.num_tets())
            .filter(|&t| region.contains_element(&mesh.tets[t].map(|v| mesh.rest[v])))
            .collect();
        if self.found_anywhere(selected.len()) == 0 {
            return Err(self.invalid(
                field,
                format!(
                    "the {} contains no element centroid of the mesh",
                    region.describe()
                ),
            ));
        }
        Ok(selected)
    }
}

/// "surface" or "volume" for a group of dimension 2 or 3.
fn kind_name(dim: u8) -> &'static str {
    if dim == 3 {
        "volume"
    } else {
        "surface"
    }
}
