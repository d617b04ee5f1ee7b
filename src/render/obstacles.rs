//! A stored run's rigid obstacles as triangle surfaces with their motion, for pictures and
//! exports: the scene text the file keeps says which obstacles there were; the surfaces are
//!
//! - a container (an open-top box): its floor and four walls, two triangles each, facing
//!   into the box;
//! - a half-space: a square on its plane, two triangles facing out of the solid side, centred
//!   on the ice's box projected onto the plane, 1.5 × that box's diagonal across — a plane is
//!   infinite, an export needs an end (pictures draw the plane itself, see
//!   `super::scenery`; this square only sizes their camera);
//! - a triangle mesh: the surface the file stores (`/obstacles`), or, in a file that stores
//!   none, the scene's surface file where it is found.

use std::path::{Path, PathBuf};

use nalgebra::Vector3;

use crate::mesh::surface::TriSurface;
use crate::output::{FrameReader, ObstacleMesh, OutputError};
use crate::physics::{Amplitude, Motion};
use crate::scene::{ObstacleSection, SceneFile};

/// One rigid obstacle of a stored run.
#[derive(Clone, Debug)]
pub struct StoredObstacle {
    /// Its index among the scene's `[[obstacle]]` sections.
    pub index: usize,
    /// `container`, `halfspace` or `mesh`.
    pub kind: String,
    /// Its surface at t = 0 (m).
    pub surface: TriSurface,
    /// How it moves.
    pub motion: Motion,
}

impl StoredObstacle {
    /// The surface's vertices at time `t` (s), m.
    pub fn vertices_at(&self, t: f64) -> Vec<Vector3<f64>> {
        self.surface
            .vertices
            .iter()
            .map(|x| self.motion.position(t, x))
            .collect()
    }

    /// The surface's vertices' velocities at time `t` (s), m/s.
    pub fn velocities_at(&self, t: f64) -> Vec<Vector3<f64>> {
        self.surface
            .vertices
            .iter()
            .map(|x| self.motion.velocity_at(t, &self.motion.position(t, x)))
            .collect()
    }
}

/// The rigid obstacles of `reader`'s run, half-spaces sized to the ice's box `ice_box()`
/// (lo, hi in m; asked for only when the scene has a half-space). A scene text that no longer
/// parses (another version) or an obstacle whose surface file is gone gives no obstacle: the
/// run's own output does not depend on them.
pub fn stored_obstacles(
    reader: &FrameReader,
    ice_box: impl FnOnce() -> Result<(Vector3<f64>, Vector3<f64>), OutputError>,
) -> Result<Vec<StoredObstacle>, OutputError> {
    let surfaces = ObstacleSurfaces {
        stored: reader.obstacle_meshes()?,
        scene_dirs: scene_dirs(reader),
    };
    let Ok(scene) = toml::from_str::<SceneFile>(reader.scene_text()) else {
        return Ok(Vec::new());
    };
    let (lo, hi) = if scene.obstacle.iter().any(|o| o.kind == "halfspace") {
        ice_box()?
    } else {
        (Vector3::zeros(), Vector3::zeros())
    };
    Ok(scene
        .obstacle
        .iter()
        .enumerate()
        .filter_map(|(index, o)| {
            let v3 = |v: Option<[f64; 3]>| v.map(Vector3::from);
            let surface = match o.kind.as_str() {
                "container" => container(v3(o.min)?, v3(o.max)?),
                "halfspace" => {
                    plane_square(v3(o.point)?, v3(o.normal)?.try_normalize(0.0)?, lo, hi)
                }
                "mesh" => surfaces.surface(index, o)?,
                _ => return None,
            };
            Some(StoredObstacle {
                index,
                kind: o.kind.clone(),
                surface,
                motion: Motion {
                    velocity: v3(o.velocity).unwrap_or_default(),
                    angular_velocity: v3(o.angular_velocity).unwrap_or_default(),
                    centre: v3(o.centre).unwrap_or_default(),
                    amplitude: o
                        .amplitude
                        .as_ref()
                        .and_then(|p| Amplitude::new(p.iter().map(|&[t, a]| (t, a)).collect()).ok())
                        .unwrap_or_default(),
                },
            })
        })
        .collect())
}

/// The floor and four walls of the open-top box `[a, b]`, facing into it.
pub(super) fn container(a: Vector3<f64>, b: Vector3<f64>) -> TriSurface {
    // Corners: bit 0 x, bit 1 y, bit 2 z (0: a, 1: b).
    let vertices = (0..8)
        .map(|i| {
            let pick = |bit: usize, k: usize| if i & bit == 0 { a[k] } else { b[k] };
            Vector3::new(pick(1, 0), pick(2, 1), pick(4, 2))
        })
        .collect();
    // Each quad counter-clockwise seen from inside the box.
    let quads = [
        [0, 1, 3, 2], // floor
        [0, 4, 5, 1], // y = a.y
        [2, 3, 7, 6], // y = b.y
        [0, 2, 6, 4], // x = a.x
        [1, 5, 7, 3], // x = b.x
    ];
    TriSurface {
        vertices,
        triangles: quads
            .iter()
            .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
            .collect(),
    }
}

/// A square on the plane through `point` with unit `normal`, facing along the normal (out of
/// the solid side), centred on the ice's box `[lo, hi]` projected onto it.
fn plane_square(
    point: Vector3<f64>,
    normal: Vector3<f64>,
    lo: Vector3<f64>,
    hi: Vector3<f64>,
) -> TriSurface {
    let centre = (lo + hi) / 2.0;
    let c = centre - normal * (centre - point).dot(&normal);
    let helper = if normal.x.abs() < 0.9 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    let t = normal.cross(&helper).normalize();
    let s = normal.cross(&t);
    let r = 0.75 * (hi - lo).norm().max(1e-9);
    let vertices = [(1.0, 1.0), (-1.0, 1.0), (-1.0, -1.0), (1.0, -1.0)]
        .iter()
        .map(|&(u, v)| c + t * (r * u) + s * (r * v))
        .collect();
    // (t, s, normal) is right-handed, so corners in this order turn about the normal.
    TriSurface {
        vertices,
        triangles: vec![[0, 1, 2], [0, 2, 3]],
    }
}

/// Where the triangle surfaces of a file's mesh obstacles come from.
struct ObstacleSurfaces {
    /// The surfaces stored in the file (`/obstacles`), as the run placed them.
    stored: Vec<ObstacleMesh>,
    /// Folders to look for a surface file in, for a file that stores none (written before
    /// they were stored): the scene's folder, and for a scene path relative to where that run
    /// was started, that folder from the HDF5 file's.
    scene_dirs: Vec<PathBuf>,
}

impl ObstacleSurfaces {
    /// The surface of obstacle `index` at t = 0 (m): the stored one, or the scene's `file`
    /// (times `scale`, moved by `translate`) where it is found.
    fn surface(&self, index: usize, o: &ObstacleSection) -> Option<TriSurface> {
        if let Some(m) = self.stored.iter().find(|m| m.index == index) {
            return Some(TriSurface {
                vertices: m.vertices.iter().map(|&v| Vector3::from(v)).collect(),
                triangles: m.triangles.clone(),
            });
        }
        let file = o.file.as_ref()?;
        let mut surface = self
            .scene_dirs
            .iter()
            .find_map(|dir| TriSurface::read(&dir.join(file), o.scale.unwrap_or(1.0)).ok())?;
        let shift = o.translate.map(Vector3::from).unwrap_or_default();
        for v in &mut surface.vertices {
            *v += shift;
        }
        Some(surface)
    }
}

/// The folders a file's scene may be in (see [`ObstacleSurfaces::scene_dirs`]).
fn scene_dirs(reader: &FrameReader) -> Vec<PathBuf> {
    let scene = Path::new(reader.scene_path());
    let Some(dir) = scene.parent() else {
        return Vec::new();
    };
    let mut dirs = vec![dir.to_path_buf()];
    if scene.is_relative() {
        if let Some(h5_dir) = reader.path().parent() {
            dirs.push(h5_dir.join(dir));
        }
    }
    dirs
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Σ area × unit normal of each triangle.
    fn area_vector(s: &TriSurface) -> Vector3<f64> {
        s.triangles
            .iter()
            .map(|t| {
                let x = t.map(|i| s.vertices[i]);
                (x[1] - x[0]).cross(&(x[2] - x[0])) / 2.0
            })
            .sum()
    }

    #[test]
    fn a_container_is_its_floor_and_walls_facing_in() {
        let s = container(Vector3::zeros(), Vector3::new(0.1, 0.2, 0.3));
        assert_eq!(s.triangles.len(), 10);
        // Open at the top: the walls' area vectors cancel, the floor's points up, into the
        // box (0.1 × 0.2 m²).
        let a = area_vector(&s);
        assert!((a - Vector3::new(0.0, 0.0, 0.02)).norm() < 1e-15, "{a}");
        let area: f64 = s
            .triangles
            .iter()
            .map(|t| {
                let x = t.map(|i| s.vertices[i]);
                (x[1] - x[0]).cross(&(x[2] - x[0])).norm() / 2.0
            })
            .sum();
        assert!((area - (0.02 + 2.0 * 0.03 + 2.0 * 0.06)).abs() < 1e-15);
        // Every wall faces the box's centre.
        let centre = Vector3::new(0.05, 0.1, 0.15);
        for t in &s.triangles {
            let x = t.map(|i| s.vertices[i]);
            let n = (x[1] - x[0]).cross(&(x[2] - x[0]));
            assert!(n.dot(&(centre - x[0])) > 0.0, "{t:?}");
        }
    }

    #[test]
    fn a_plane_is_a_square_facing_along_its_normal_under_the_ice() {
        let normal = Vector3::new(0.0, 0.6, 0.8);
        let (lo, hi) = (Vector3::new(-0.1, -0.1, 0.0), Vector3::new(0.1, 0.1, 0.2));
        let s = plane_square(Vector3::zeros(), normal, lo, hi);
        let a = area_vector(&s);
        let side = 1.5 * (hi - lo).norm();
        assert!((a - normal * side * side).norm() < 1e-12, "{a}");
        for v in &s.vertices {
            assert!(v.dot(&normal).abs() < 1e-15);
        }
        let centre: Vector3<f64> = s.vertices.iter().sum::<Vector3<f64>>() / 4.0;
        let ice = (lo + hi) / 2.0;
        assert!((centre - (ice - normal * ice.dot(&normal))).norm() < 1e-15);
    }
}
