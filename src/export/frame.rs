//! One frame as every format writes it: the ice's outer surface and the crack surfaces, each
//! a triangle mesh over points of its own with per-point attributes.
//!
//! Element fields become point fields by averaging over the elements around each node,
//! weighted by their rest volumes: v(i) = Σ_e |V_e| v_e / Σ_e |V_e| over the tets e that
//! contain node i. Velocities and temperatures are the nodes' own.

use std::path::Path;

use crate::mesh::TetMesh;
use crate::output::{FrameMesh, OutputError, StoredFrame, SurfaceExtractor};
use crate::render::obstacles::StoredObstacle;

/// Name of the freeze-state attribute: 0 (water) … 1 (ice).
pub const FREEZE_STATE: &str = "freeze_state";
/// Name of the plastic-strain attribute: ‖ε_p‖, the Frobenius norm of the plastic strain.
pub const PLASTIC_STRAIN: &str = "plastic_strain";
/// Name of the von Mises stress attribute (Pa).
pub const VON_MISES: &str = "von_mises";
/// Name of the temperature attribute (°C; runs with `[thermal]`).
pub const TEMPERATURE: &str = "temperature";
/// Name of the velocity attribute (m/s, three components).
pub const VELOCITY: &str = "velocity";

/// A scalar attribute, one value per point.
#[derive(Clone, Debug, PartialEq)]
pub struct PointScalar {
    /// [`FREEZE_STATE`], [`PLASTIC_STRAIN`], [`VON_MISES`] or [`TEMPERATURE`].
    pub name: &'static str,
    /// One value per point.
    pub values: Vec<f64>,
}

/// A triangle mesh with per-point attributes.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SurfaceMesh {
    /// Point positions (m; z up).
    pub points: Vec<[f64; 3]>,
    /// Triangles, 0-based point indices, counter-clockwise seen from outside the ice.
    pub triangles: Vec<[usize; 3]>,
    /// The scalar attributes the run has (a run without freezing has no freeze state, one
    /// without plasticity no plastic strain, one without `[thermal]` no temperature), in the
    /// order freeze state, plastic strain, von Mises, temperature.
    pub scalars: Vec<PointScalar>,
    /// Velocity of each point (m/s).
    pub velocity: Vec<[f64; 3]>,
}

/// One exported frame.
#[derive(Clone, Debug, PartialEq)]
pub struct ExportFrame {
    /// Its number in the export: 0, 1, 2, … whatever the run's frame indices.
    pub number: usize,
    /// The run's frame index (`/frames/NNNNNN`).
    pub index: usize,
    /// Simulated time (s).
    pub time: f64,
    /// The ice's outer surface: the boundary faces of the frame's tets that are not crack
    /// faces, over the nodes they use.
    pub ice: SurfaceMesh,
    /// The crack surfaces: the frame's `cracks/` triangles, three points each, where the run
    /// drew them (pulled apart by the rendering gap where a crack is closed); each point
    /// takes the attributes of the node it is a copy of. Empty before the first crack.
    pub cracks: SurfaceMesh,
    /// The rigid obstacles' surfaces where they are at the frame's time, one mesh (a
    /// container's floor and walls, a plane's square, a mesh obstacle's triangles), with the
    /// points' velocities and no scalars; `None` for a run without obstacles.
    pub obstacles: Option<SurfaceMesh>,
}

impl ExportFrame {
    /// Builds frame `number` of the export from `frame`, read from the file `path` whose
    /// surfaces `extractor` finds and whose run had the rigid `obstacles`.
    pub fn new(
        extractor: &SurfaceExtractor,
        path: &Path,
        frame: &StoredFrame,
        number: usize,
        obstacles: &[StoredObstacle],
    ) -> Result<Self, OutputError> {
        let mesh = extractor.mesh(path, frame)?;
        let fields = NodeFields::new(&mesh.rest, frame);
        let ice = ice_surface(&mesh, frame, &fields);
        let cracks = crack_surface(&mesh, path, frame, &fields)?;
        Ok(ExportFrame {
            number,
            index: frame.index,
            time: frame.state.time,
            ice,
            cracks,
            obstacles: (!obstacles.is_empty())
                .then(|| obstacle_surface(obstacles, frame.state.time)),
        })
    }
}

/// The surfaces of `obstacles` at time `t` (s) as one mesh, with their points' velocities.
fn obstacle_surface(obstacles: &[StoredObstacle], t: f64) -> SurfaceMesh {
    let mut mesh = SurfaceMesh::default();
    for o in obstacles {
        let offset = mesh.points.len();
        mesh.points
            .extend(o.vertices_at(t).iter().map(|x| [x.x, x.y, x.z]));
        mesh.velocity
            .extend(o.velocities_at(t).iter().map(|v| [v.x, v.y, v.z]));
        mesh.triangles.extend(
            o.surface
                .triangles
                .iter()
                .map(|tri| tri.map(|i| i + offset)),
        );
    }
    mesh
}

/// Every node's attributes: element fields averaged to the nodes, the nodes' temperatures,
/// and velocities.
struct NodeFields<'a> {
    scalars: Vec<(&'static str, Vec<f64>)>,
    velocity: &'a [[f64; 3]],
}

impl<'a> NodeFields<'a> {
    fn new(mesh: &TetMesh, frame: &'a StoredFrame) -> Self {
        let element_fields = [
            (FREEZE_STATE, frame.freeze_state().map(<[f64]>::to_vec)),
            (PLASTIC_STRAIN, frame.plastic_strain_norm()),
            (VON_MISES, frame.von_mises()),
        ];
        let weights: Vec<f64> = (0..mesh.num_tets())
            .map(|t| mesh.signed_volume(t).abs())
            .collect();
        let mut total = vec![0.0; mesh.num_nodes()];
        for (tet, w) in mesh.tets.iter().zip(&weights) {
            for &i in tet {
                total[i] += w;
            }
        }
        let mut scalars: Vec<(&'static str, Vec<f64>)> = element_fields
            .into_iter()
            .filter_map(|(name, values)| {
                let values = values?;
                let mut sum = vec![0.0; mesh.num_nodes()];
                for ((tet, w), v) in mesh.tets.iter().zip(&weights).zip(&values) {
                    for &i in tet {
                        sum[i] += w * v;
                    }
                }
                for (s, t) in sum.iter_mut().zip(&total) {
                    *s = if *t > 0.0 { *s / t } else { 0.0 };
                }
                Some((name, sum))
            })
            .collect();
        if let Some((1, temperature)) = frame.node_field(TEMPERATURE) {
            if temperature.len() == mesh.num_nodes() {
                scalars.push((TEMPERATURE, temperature.to_vec()));
            }
        }
        NodeFields {
            scalars,
            velocity: &frame.state.velocities,
        }
    }

    /// A surface over points that are copies of `nodes`, at `points`.
    fn surface(
        &self,
        points: Vec<[f64; 3]>,
        triangles: Vec<[usize; 3]>,
        nodes: &[usize],
    ) -> SurfaceMesh {
        SurfaceMesh {
            points,
            triangles,
            scalars: self
                .scalars
                .iter()
                .map(|(name, values)| PointScalar {
                    name,
                    values: nodes.iter().map(|&i| values[i]).collect(),
                })
                .collect(),
            velocity: nodes.iter().map(|&i| self.velocity[i]).collect(),
        }
    }
}

/// The outer faces over the nodes they use, in ascending node order.
fn ice_surface(mesh: &FrameMesh, frame: &StoredFrame, fields: &NodeFields) -> SurfaceMesh {
    let faces = mesh.outer_faces(None);
    let mut point_of = vec![usize::MAX; mesh.rest.num_nodes()];
    for f in &faces {
        for &i in &f.nodes {
            point_of[i] = 0;
        }
    }
    let mut nodes = Vec::new();
    for (i, p) in point_of.iter_mut().enumerate() {
        if *p == 0 {
            *p = nodes.len();
            nodes.push(i);
        }
    }
    let points = nodes.iter().map(|&i| frame.state.positions[i]).collect();
    let triangles = faces.iter().map(|f| f.nodes.map(|i| point_of[i])).collect();
    fields.surface(points, triangles, &nodes)
}

/// The frame's crack triangles, each vertex with the attributes of its node.
fn crack_surface(
    mesh: &FrameMesh,
    path: &Path,
    frame: &StoredFrame,
    fields: &NodeFields,
) -> Result<SurfaceMesh, OutputError> {
    let stored = &frame.crack_triangles;
    if stored.is_empty() {
        return Ok(fields.surface(Vec::new(), Vec::new(), &[]));
    }
    let faces = mesh.crack_faces();
    if faces.len() != stored.len() {
        return Err(OutputError::Corrupt {
            path: path.to_path_buf(),
            reason: format!(
                "frame {}: cracks/ has {} triangles, its mesh {} crack faces",
                frame.index,
                stored.len(),
                faces.len()
            ),
        });
    }
    let points = stored.iter().flat_map(|(x, _)| *x).collect();
    let triangles = (0..stored.len())
        .map(|k| [3 * k, 3 * k + 1, 3 * k + 2])
        .collect();
    let nodes: Vec<usize> = faces.iter().flat_map(|f| f.nodes).collect();
    Ok(fields.surface(points, triangles, &nodes))
}
