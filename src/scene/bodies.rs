//! The scene's mesh: `[mesh]` (boxes or a Gmsh file), or `[[body]]`: several bodies, each a
//! box or a Gmsh mesh placed by scale, rotation and translation, with an initial velocity and
//! spin; `[initial]`: a start from a frame of an earlier run; and the reading of Gmsh meshes
//! for bodies and for `[mesh] file`.

use nalgebra::{Rotation3, Unit, Vector3};
use serde::Deserialize;
use std::path::Path;

use super::{BoxSection, MeshSection, SceneError, SceneFile, Validator};
use crate::mesh::{box_mesh, gmsh, reorient, BoxGrid, MeshError, TetMesh};
use crate::physics::Group;
use std::ops::Range;
use std::sync::Arc;

impl Validator<'_> {
    /// The mesh of `[mesh]` (everything at rest, one body), or of the `[[body]]` entries.
    pub(super) fn mesh_or_bodies(&self, raw: &SceneFile) -> Result<Bodies, SceneError> {
        match (&raw.mesh, raw.body.is_empty()) {
            (Some(m), true) => Ok(Bodies {
                mesh: self.mesh(m)?,
                velocity: Vec::new(),
                elements: Vec::new(),
            }),
            (None, false) => self.bodies(&raw.body),
            (Some(_), false) => {
                Err(self.invalid("body", "give `[mesh]` or `[[body]]` entries, not both"))
            }
            (None, true) => {
                Err(self.invalid("mesh", "missing: give `[mesh]` or `[[body]]` entries"))
            }
        }
    }

    /// The mesh of `[mesh]`: the built-in boxes or a Gmsh file; on this process's part only
    /// where the scene is built on parts (see `shared`).
    fn mesh(&self, m: &MeshSection) -> Result<TetMesh, SceneError> {
        let mesh_err = |source| SceneError::Mesh {
            path: self.path.into(),
            source,
        };
        let boxes: Vec<&BoxSection> = match (&m.box_, &m.boxes) {
            (Some(b), None) => vec![b],
            (None, Some(list)) if !list.is_empty() => list.iter().collect(),
            (None, Some(_)) => return Err(self.invalid("mesh.boxes", "must list at least one box")),
            (Some(_), Some(_)) => {
                return Err(self.invalid("mesh", "give `box` or `boxes`, not both"))
            }
            (None, None) => Vec::new(),
        };
        match (boxes.is_empty(), &m.file) {
            (false, None) => {
                if m.scale.is_some() {
                    return Err(self.invalid("mesh.scale", "applies to mesh files only"));
                }
                let field = |k: usize| {
                    if m.boxes.is_some() {
                        format!("mesh.boxes[{k}]")
                    } else {
                        "mesh.box".into()
                    }
                };
                self.check_boxes(&boxes, field)?;
                if self.sharing.get().is_some() {
                    // One box (`builds_on_parts`): each process makes its ranges only.
                    let b = boxes[0];
                    let tpc = b.tets_per_cell.unwrap_or(6);
                    let grid = BoxGrid::new(b.origin, b.size, b.cells, tpc).map_err(mesh_err)?;
                    return self.share_grid(&grid);
                }
                let mut parts = Vec::with_capacity(boxes.len());
                for b in &boxes {
                    let tpc = b.tets_per_cell.unwrap_or(6);
                    parts.push(box_mesh(b.origin, b.size, b.cells, tpc).map_err(mesh_err)?);
                }
                TetMesh::concat(parts).map_err(mesh_err)
            }
            (true, Some(file)) => {
                let scale = self.positive("mesh.scale", m.scale.unwrap_or(1.0))?;
                let (mesh, groups) = self.gmsh_file("mesh.file", file, scale)?;
                self.check_parts_apart("mesh.file", &mesh)?;
                self.add_groups("mesh.file", geometric_groups(&mesh, &groups))?;
                // Several parts (ice–ice contact between them): built whole on every process.
                if self.sharing.get().is_some() && crate::mesh::parts(&mesh).1 > 1 {
                    self.sharing.set(None);
                    self.whole_on_every_process("a mesh of several parts (ice–ice contact)");
                }
                match self.sharing.get() {
                    Some(_) => self.share_mesh(mesh),
                    None => Ok(mesh),
                }
            }
            _ => Err(self.invalid(
                "mesh",
                "give exactly one of `box`/`boxes` (built-in generator) or `file` (Gmsh .msh)",
            )),
        }
    }
}

/// `[[body]]`: one body — a box or a Gmsh file — placed in the scene and set moving.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BodySection {
    /// Built-in box generator (in the body's own coordinates).
    #[serde(rename = "box")]
    pub box_: Option<BoxSection>,
    /// Gmsh `.msh` file, relative to the scene file.
    pub file: Option<String>,
    /// Factor applied to the file's coordinates to get metres (files only). Default 1.
    pub scale: Option<f64>,
    /// Rotation about the body's own origin, applied after `scale`.
    pub rotate: Option<RotateSection>,
    /// Translation (m), applied last. Default 0.
    pub translate: Option<[f64; 3]>,
    /// Initial velocity of the body's centroid (m/s). Default 0.
    pub velocity: Option<[f64; 3]>,
    /// Initial angular velocity about the body's centroid (rad/s). Default 0.
    pub angular_velocity: Option<[f64; 3]>,
    /// Name of a `[materials.NAME]` entry the body is made of. Default: `[material]`.
    pub material: Option<String>,
}

/// `rotate = { axis, degrees }`: a rotation by `degrees` about `axis` (right-hand rule).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RotateSection {
    /// Axis (any non-zero length).
    pub axis: [f64; 3],
    /// Angle (degrees).
    pub degrees: f64,
}

/// `[initial]`: start from the displacement and velocity of a frame of an earlier run on the
/// same mesh (the element history — plastic strain, freeze state — starts afresh).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InitialSection {
    /// The earlier run's HDF5 file, relative to the scene file.
    pub file: String,
    /// Frame index. Default: the last complete frame.
    pub frame: Option<usize>,
}

impl Validator<'_> {
    /// The displacement and velocity (3 per node) of the frame `initial` names, checked to be
    /// on `mesh` (same nodes at the same rest positions, same tets).
    pub(super) fn initial_state(
        &self,
        initial: &InitialSection,
        mesh: &TetMesh,
    ) -> Result<(Vec<f64>, Vec<f64>), SceneError> {
        let file = self
            .path
            .parent()
            .unwrap_or(Path::new(""))
            .join(&initial.file);
        let read_error =
            |e: crate::output::OutputError| self.invalid("initial.file", e.to_string());
        let reader = crate::output::FrameReader::open(&file).map_err(read_error)?;
        let index = match initial.frame {
            Some(k) => k,
            None => *reader.frame_indices().last().unwrap_or(&0),
        };
        let frame = reader
            .read(index)
            .map_err(|e| self.invalid("initial.frame", e.to_string()))?
            .state;
        let same_rest = frame.rest_positions.len() == mesh.num_nodes()
            && frame
                .rest_positions
                .iter()
                .zip(&mesh.rest)
                .all(|(p, x)| (Vector3::from(*p) - x).norm() <= 1e-12 * (1.0 + x.norm()));
        if !same_rest || frame.tets != mesh.tets {
            return Err(self.invalid(
                "initial",
                format!(
                    "frame {index} of {} is on another mesh ({} nodes, {} tets; this scene's: {} nodes, {} tets, or the same counts at other rest positions); a fractured frame cannot start a new run (use --resume)",
                    file.display(),
                    frame.rest_positions.len(),
                    frame.tets.len(),
                    mesh.num_nodes(),
                    mesh.num_tets()
                ),
            ));
        }
        // The stored displacement as written (positions − rest would round it).
        let displacement = match frame.node_fields.iter().find(|f| f.name == "displacement") {
            Some(f) if f.columns == 3 && f.data.len() == 3 * mesh.num_nodes() => f.data.clone(),
            _ => frame
                .positions
                .iter()
                .zip(&frame.rest_positions)
                .flat_map(|(x, p)| [x[0] - p[0], x[1] - p[1], x[2] - p[2]])
                .collect(),
        };
        let velocity = frame.velocities.iter().flatten().copied().collect();
        Ok((displacement, velocity))
    }

    /// The bodies as one mesh (each body its own nodes, its files' named groups registered),
    /// each node's initial velocity (m/s, 3 per node; empty when every body starts at rest),
    /// and each body's range of elements.
    pub(super) fn bodies(&self, bodies: &[BodySection]) -> Result<Bodies, SceneError> {
        if bodies.is_empty() {
            return Err(self.invalid("body", "must list at least one body"));
        }
        let mut meshes = Vec::with_capacity(bodies.len());
        let mut velocities = Vec::with_capacity(bodies.len());
        let mut groups = Vec::new();
        let mut elements = Vec::with_capacity(bodies.len());
        let mut first = 0;
        for (k, body) in bodies.iter().enumerate() {
            let field = format!("body[{k}]");
            let mut file_groups = Vec::new();
            let mut mesh = match (&body.box_, &body.file) {
                (Some(b), None) => {
                    if body.scale.is_some() {
                        return Err(
                            self.invalid(&format!("{field}.scale"), "applies to mesh files only")
                        );
                    }
                    let box_field = format!("{field}.box");
                    self.check_boxes(&[b], |_| box_field.clone())?;
                    box_mesh(b.origin, b.size, b.cells, b.tets_per_cell.unwrap_or(6))
                        .map_err(|source| self.mesh_error(source))?
                }
                (None, Some(file)) => {
                    let scale =
                        self.positive(&format!("{field}.scale"), body.scale.unwrap_or(1.0))?;
                    let (mesh, named) = self.gmsh_file(&format!("{field}.file"), file, scale)?;
                    file_groups = named;
                    mesh
                }
                _ => {
                    return Err(self.invalid(
                        &field,
                        "give exactly one of `box` (built-in generator) or `file` (Gmsh .msh)",
                    ))
                }
            };
            let rotation = match &body.rotate {
                None => Rotation3::identity(),
                Some(r) => {
                    let axis = self.vector(&format!("{field}.rotate.axis"), r.axis)?;
                    let degrees = self.finite(&format!("{field}.rotate.degrees"), r.degrees)?;
                    let axis = Unit::try_new(axis, 0.0).ok_or_else(|| {
                        self.invalid(&format!("{field}.rotate.axis"), "must not be zero")
                    })?;
                    Rotation3::from_axis_angle(&axis, degrees.to_radians())
                }
            };
            let translate = self.vector(
                &format!("{field}.translate"),
                body.translate.unwrap_or_default(),
            )?;
            for x in &mut mesh.rest {
                *x = rotation * *x + translate;
            }
            groups.extend(geometric_groups(&mesh, &file_groups));
            elements.push(first..first + mesh.num_tets());
            first += mesh.num_tets();
            let velocity = self.vector(
                &format!("{field}.velocity"),
                body.velocity.unwrap_or_default(),
            )?;
            let spin = self.vector(
                &format!("{field}.angular_velocity"),
                body.angular_velocity.unwrap_or_default(),
            )?;
            let centroid = centroid(&mesh);
            velocities.push(
                mesh.rest
                    .iter()
                    .flat_map(|x| {
                        let v = velocity + spin.cross(&(x - centroid));
                        [v.x, v.y, v.z]
                    })
                    .collect::<Vec<f64>>(),
            );
            meshes.push(mesh);
        }
        let mesh = TetMesh::concat(meshes).map_err(|source| self.mesh_error(source))?;
        self.check_memory("body", mesh.num_tets() as u128, "use coarser bodies")?;
        self.check_parts_apart("body", &mesh)?;
        let moving = velocities.iter().flatten().any(|&v| v != 0.0);
        let velocity = if moving {
            velocities.concat()
        } else {
            Vec::new()
        };
        self.add_groups("body", groups)?;
        Ok(Bodies {
            mesh,
            velocity,
            elements,
        })
    }

    /// Registers named groups for `region = "NAME"`: groups of one name from several files
    /// are one group; a name may not be both a volume and a surface.
    pub(super) fn add_groups(&self, field: &str, groups: Vec<Group>) -> Result<(), SceneError> {
        let mut known = self.groups.borrow_mut();
        for group in groups {
            match known.iter_mut().find(|g| g.name == group.name) {
                Some(g) if g.dim != group.dim => {
                    return Err(self.invalid(
                        field,
                        format!(
                        "physical group {:?} is a volume in one mesh file and a surface in another",
                        group.name
                    ),
                    ))
                }
                Some(g) => *g = Arc::new(g.merged(&group)),
                None => known.push(Arc::new(group)),
            }
        }
        Ok(())
    }

    /// The tets of the Gmsh file `file` (relative to the scene file), coordinates times
    /// `scale`, and its named physical groups: negatively oriented tets are used reoriented
    /// (with a notice), and errors quote the file's own node and element tags.
    pub(super) fn gmsh_file(
        &self,
        field: &str,
        file: &str,
        scale: f64,
    ) -> Result<(TetMesh, Vec<gmsh::PhysicalGroup>), SceneError> {
        let file = self.path.parent().unwrap_or(Path::new("")).join(file);
        let gmsh::TetFile {
            nodes,
            mut tets,
            node_tags,
            element_tags,
            groups,
        } = gmsh::read_msh_tagged(&file).map_err(|source| SceneError::MeshFile {
            path: self.path.into(),
            source,
        })?;
        let nodes: Vec<[f64; 3]> = nodes.iter().map(|p| p.map(|c| c * scale)).collect();
        // The file's arrays are small next to what a run builds on them.
        self.check_memory(field, tets.len() as u128, "use a coarser mesh")?;
        let swapped = reorient(&nodes, &mut tets);
        if swapped > 0 {
            self.notices.borrow_mut().push(format!(
                "{}: {swapped} of {} tetrahedra were negatively oriented and are used with two vertices swapped",
                file.display(),
                tets.len()
            ));
        }
        let mesh = TetMesh::from_arrays(&nodes, tets).map_err(|source| {
            self.mesh_error(MeshError::InFile(format!(
                "mesh file {}: {}",
                file.display(),
                source.in_file(&node_tags, &element_tags)
            )))
        })?;
        Ok((mesh, groups))
    }

    /// A mesh error of this scene file.
    pub(super) fn mesh_error(&self, source: MeshError) -> SceneError {
        SceneError::Mesh {
            path: self.path.into(),
            source,
        }
    }
}

/// The bodies of a scene as one mesh.
pub(super) struct Bodies {
    /// All bodies' elements, body by body.
    pub mesh: TetMesh,
    /// Initial velocity of each node (m/s, 3 per node); empty: all at rest.
    pub velocity: Vec<f64>,
    /// Each body's elements in `mesh`.
    pub elements: Vec<Range<usize>>,
}

/// A file's named groups on `mesh` (its rest positions as placed in the scene).
pub(super) fn geometric_groups(mesh: &TetMesh, groups: &[gmsh::PhysicalGroup]) -> Vec<Group> {
    let x = |i: usize| mesh.rest[i];
    groups
        .iter()
        .map(|g| {
            if g.dim == 3 {
                let tets: Vec<_> = g.tets.iter().map(|&t| mesh.tets[t].map(x)).collect();
                Group::volume(&g.name, &tets)
            } else {
                let triangles: Vec<_> = g.triangles.iter().map(|t| t.map(x)).collect();
                Group::surface(&g.name, &triangles)
            }
        })
        .collect()
}

/// Volume-weighted centroid of a mesh's rest configuration (m): its centre of mass for a
/// uniform density.
fn centroid(mesh: &TetMesh) -> Vector3<f64> {
    let (mut sum, mut volume) = (Vector3::zeros(), 0.0);
    for (t, tet) in mesh.tets.iter().enumerate() {
        let v = mesh.signed_volume(t);
        let c = tet.iter().map(|&i| mesh.rest[i]).sum::<Vector3<f64>>() / 4.0;
        sum += v * c;
        volume += v;
    }
    sum / volume
}
