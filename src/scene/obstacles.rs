//! `[[obstacle]]`: rigid obstacles — half-space, open-top container, triangle mesh — and
//! their motion.

use super::{SceneError, Validator};
use crate::fem::Material;
use crate::mesh::surface::TriSurface;
use crate::mesh::TetMesh;
use crate::physics::contact::Shape;
use crate::physics::obstacle_mesh::ObstacleSurface;
use crate::physics::{Motion, Obstacle};
use serde::Deserialize;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// `[[obstacle]]`: a rigid obstacle, `type = "halfspace"` (with `point`, `normal`),
/// `type = "container"` (open-top box with inner corners `min`, `max`) or `type = "mesh"`
/// (a triangle surface from `file`, OBJ or Gmsh, times `scale`, moved by `translate`).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObstacleSection {
    /// "halfspace", "container" or "mesh".
    #[serde(rename = "type")]
    pub kind: String,
    /// Mesh: surface file (.obj or .msh), relative to the scene file.
    pub file: Option<PathBuf>,
    /// Mesh: factor applied to the file's coordinates (to metres). Default 1.
    pub scale: Option<f64>,
    /// Mesh: translation applied after scaling (m). Default 0.
    pub translate: Option<[f64; 3]>,
    /// Half-space: a point on its surface (m).
    pub point: Option<[f64; 3]>,
    /// Half-space: normal pointing out of the obstacle (normalised here).
    pub normal: Option<[f64; 3]>,
    /// Container: inner lower corner (m).
    pub min: Option<[f64; 3]>,
    /// Container: inner upper corner (m); its z is the rim (the top is open).
    pub max: Option<[f64; 3]>,
    /// Rigid velocity (m/s). Default 0.
    pub velocity: Option<[f64; 3]>,
    /// Angular velocity (rad/s) about `centre`. Default 0.
    pub angular_velocity: Option<[f64; 3]>,
    /// The point the obstacle turns about at t = 0 (m); it moves with `velocity`. Default 0.
    pub centre: Option<[f64; 3]>,
    /// Amplitude of `velocity` and `angular_velocity` in time: [time (s), factor] points.
    /// Default 1.
    pub amplitude: Option<Vec<[f64; 2]>>,
    /// Penalty stiffness (N/m³). Default 10 E / h (h: mean boundary edge length of the ice).
    pub stiffness: Option<f64>,
    /// Coulomb friction coefficient. Default 0.
    pub friction: Option<f64>,
}

impl Validator<'_> {
    /// The obstacle of the `[[obstacle]]` entry number `i`, its penalty scaled to `mesh` of
    /// `material` unless given.
    pub(super) fn obstacle(
        &self,
        i: usize,
        o: &ObstacleSection,
        mesh: &TetMesh,
        material: &Material,
    ) -> Result<Obstacle, SceneError> {
        let field = format!("obstacle[{i}]");
        self.check_obstacle_keys(&field, o)?;
        let shape = match o.kind.as_str() {
            "halfspace" => self.half_space(&field, o)?,
            "container" => self.container(&field, o)?,
            "mesh" => self.mesh_obstacle(&field, o)?,
            other => {
                return Err(self.invalid(
                    &format!("{field}.type"),
                    format!("must be \"halfspace\", \"container\" or \"mesh\", got {other:?}"),
                ))
            }
        };
        let stiffness = self.penalty(&format!("{field}.stiffness"), o.stiffness, mesh, material)?;
        let motion = self.obstacle_motion(&field, o)?;
        Ok(Obstacle {
            shape,
            motion,
            stiffness,
            friction: self.non_negative(&format!("{field}.friction"), o.friction.unwrap_or(0.0))?,
        })
    }

    /// Refuses the keys of another type of obstacle than `o.kind`.
    fn check_obstacle_keys(&self, field: &str, o: &ObstacleSection) -> Result<(), SceneError> {
        let misplaced = [
            ("point", o.point.is_some(), "halfspace"),
            ("normal", o.normal.is_some(), "halfspace"),
            ("min", o.min.is_some(), "container"),
            ("max", o.max.is_some(), "container"),
            ("file", o.file.is_some(), "mesh"),
            ("scale", o.scale.is_some(), "mesh"),
            ("translate", o.translate.is_some(), "mesh"),
        ];
        if let Some((name, _, owner)) = misplaced
            .iter()
            .find(|(_, given, owner)| *given && *owner != o.kind)
        {
            return Err(self.invalid(
                &format!("{field}.{name}"),
                format!(
                    "belongs to type = \"{owner}\" obstacles, not \"{}\"",
                    o.kind
                ),
            ));
        }
        Ok(())
    }

    /// `type = "halfspace"`: the surface through `point` with outward `normal` (normalised).
    fn half_space(&self, field: &str, o: &ObstacleSection) -> Result<Shape, SceneError> {
        let f = |name: &str| format!("{field}.{name}");
        let point = o
            .point
            .ok_or_else(|| self.invalid(&f("point"), "missing (a point on the surface, m)"))?;
        let normal = o
            .normal
            .ok_or_else(|| self.invalid(&f("normal"), "missing (outward normal)"))?;
        let normal = self.vector(&f("normal"), normal)?;
        if normal.norm() == 0.0 {
            return Err(self.invalid(&f("normal"), "must not be zero"));
        }
        Ok(Shape::HalfSpace {
            point: self.vector(&f("point"), point)?,
            normal: normal.normalize(),
        })
    }

    /// `type = "container"`: the open-top box with inner corners `min`, `max`.
    fn container(&self, field: &str, o: &ObstacleSection) -> Result<Shape, SceneError> {
        let f = |name: &str| format!("{field}.{name}");
        let min = o
            .min
            .ok_or_else(|| self.invalid(&f("min"), "missing (inner lower corner, m)"))?;
        let max = o
            .max
            .ok_or_else(|| self.invalid(&f("max"), "missing (inner upper corner, m)"))?;
        let inner = self.region(field, min, max)?;
        if (0..3).any(|a| inner.max[a] <= inner.min[a]) {
            return Err(self.invalid(&f("max"), "must exceed `min` on every axis"));
        }
        Ok(Shape::Container { inner })
    }

    /// `type = "mesh"`: the triangle surface of `file` (relative to the scene file), times
    /// `scale`, moved by `translate`; a closed one is turned to face outward.
    fn mesh_obstacle(&self, field: &str, o: &ObstacleSection) -> Result<Shape, SceneError> {
        let f = |name: &str| format!("{field}.{name}");
        let file = o
            .file
            .as_ref()
            .ok_or_else(|| self.invalid(&f("file"), "missing (surface mesh, .obj or .msh)"))?;
        let scale = self.positive(&f("scale"), o.scale.unwrap_or(1.0))?;
        let shift = self.vector(&f("translate"), o.translate.unwrap_or_default())?;
        let file = self.path.parent().unwrap_or(Path::new("")).join(file);
        let mut surface =
            TriSurface::read(&file, scale).map_err(|source| SceneError::SurfaceFile {
                path: self.path.into(),
                field: f("file"),
                source,
            })?;
        for v in &mut surface.vertices {
            *v += shift;
        }
        let reversed = surface.orient_outward().map_err(|problem| {
            self.invalid(&f("file"), format!("{}: {problem}", file.display()))
        })?;
        if reversed > 0 {
            self.notices.borrow_mut().push(format!(
                "{}: {reversed} of {} triangles faced into the obstacle and are used reversed (the surface is closed: its triangles are turned to face out of it)",
                file.display(),
                surface.triangles.len()
            ));
        }
        Ok(Shape::Mesh {
            surface: Arc::new(ObstacleSurface::new(&surface)),
        })
    }

    /// How the obstacle moves: `velocity`, and `angular_velocity` about `centre`, scaled in
    /// time by `amplitude`.
    fn obstacle_motion(&self, field: &str, o: &ObstacleSection) -> Result<Motion, SceneError> {
        let f = |name: &str| format!("{field}.{name}");
        if o.centre.is_some() && o.angular_velocity.is_none() {
            return Err(self.invalid(
                &f("centre"),
                "is the point the obstacle turns about: give `angular_velocity` with it",
            ));
        }
        if o.amplitude.is_some() && o.velocity.is_none() && o.angular_velocity.is_none() {
            return Err(self.invalid(
                &f("amplitude"),
                "scales the obstacle's `velocity` and `angular_velocity`: give one of them",
            ));
        }
        Ok(Motion {
            velocity: self.vector(&f("velocity"), o.velocity.unwrap_or_default())?,
            angular_velocity: self.vector(
                &f("angular_velocity"),
                o.angular_velocity.unwrap_or_default(),
            )?,
            centre: self.vector(&f("centre"), o.centre.unwrap_or_default())?,
            amplitude: self.amplitude(&f("amplitude"), &o.amplitude)?,
        })
    }
}
