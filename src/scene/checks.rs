//! The checks of a scene's input that look past single fields: what the whole mesh needs of
//! the machine's memory, bodies that overlap, ice that starts inside an obstacle, and penalty
//! stiffnesses far from the ice's own.

use nalgebra::Vector3;

use super::{BoxSection, SceneError, Validator};
use crate::fem::Material;
use crate::mesh::parts;
use crate::mesh::TetMesh;
use crate::physics::contact::{stiffness_for_edge, Shape};
use crate::physics::grid::BoxGrid;
use crate::physics::Obstacle;

/// Allowed penalty stiffnesses, as factors of the default 10 E / h (h: the ice's mean boundary
/// edge): the penetration under a load stays between 1e-4 and 1e2 times what the default gives.
const PENALTY_RANGE: (f64, f64) = (1e-2, 1e4);

/// Memory a tet of a scene takes in a run, for refusing a mesh that cannot fit before it is
/// built (bytes): the benchmarks measured 2.6 GB for 2e6 tets with the Cholesky solver.
const BYTES_PER_TET: f64 = 1.3e3;

/// Memory this machine has available (bytes, `MemAvailable` of /proc/meminfo), if it can tell.
fn available_memory() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

/// The memory a process needs for its share of `tets` tets run on `processes` processes and
/// the memory it has, `available` bytes shared by the `local` processes on its machine
/// (bytes), if it needs more than it has.
fn memory_short(
    tets: u128,
    (processes, local): (usize, usize),
    available: u64,
) -> Option<(f64, f64)> {
    let needed = tets as f64 * BYTES_PER_TET / processes.max(1) as f64;
    let has = available as f64 / local.max(1) as f64;
    (needed > has).then_some((needed, has))
}

impl Validator<'_> {
    /// Checks the boxes of `[mesh]` before any is meshed: sizes, cells, tets per cell; that
    /// the whole mesh fits in the memory this machine has (refused in microseconds, without
    /// allocating); and that no two boxes overlap (bodies must start apart).
    pub(super) fn check_boxes(
        &self,
        boxes: &[&BoxSection],
        field: impl Fn(usize) -> String,
    ) -> Result<(), SceneError> {
        let mut tets = 0u128;
        for (k, b) in boxes.iter().enumerate() {
            let field = field(k);
            for a in 0..3 {
                self.positive(&format!("{field}.size[{a}]"), b.size[a])?;
                self.finite(&format!("{field}.origin[{a}]"), b.origin[a])?;
                if b.cells[a] == 0 {
                    return Err(self.invalid(&format!("{field}.cells[{a}]"), "must be ≥ 1"));
                }
            }
            let tpc = b.tets_per_cell.unwrap_or(6);
            if tpc != 5 && tpc != 6 {
                return Err(self.invalid(
                    &format!("{field}.tets_per_cell"),
                    format!("must be 5 or 6, got {tpc}"),
                ));
            }
            tets += b.cells.iter().map(|&c| c as u128).product::<u128>() * tpc as u128;
        }
        self.check_memory(&field(0).replace("[0]", ""), tets, "use fewer cells")?;
        for (j, b) in boxes.iter().enumerate() {
            for (i, a) in boxes[..j].iter().enumerate() {
                let overlap: Vec<f64> = (0..3)
                    .map(|d| {
                        (a.origin[d] + a.size[d]).min(b.origin[d] + b.size[d])
                            - a.origin[d].max(b.origin[d])
                    })
                    .collect();
                // Touching faces (overlap 0 in one direction) are fine; round-off is not an
                // overlap.
                let tolerance = 1e-9 * a.size.iter().chain(&b.size).fold(0.0f64, |m, &s| m.max(s));
                if overlap.iter().all(|&o| o > tolerance) {
                    return Err(self.invalid(
                        &field(j),
                        format!(
                            "overlaps {} by {:.3e} × {:.3e} × {:.3e} m; bodies must start apart",
                            field(i),
                            overlap[0],
                            overlap[1],
                            overlap[2]
                        ),
                    ));
                }
            }
        }
        Ok(())
    }

    /// A penalty stiffness (N/m³): `given`, within [`PENALTY_RANGE`] times the default 10 E / h,
    /// or that default. Far above it the contact force of a step's penetration dwarfs the ice's
    /// own stiffness (1e25 N/m³ kicked a resting cube to 4 m/s); far below, the ice sinks into
    /// the obstacle (1e3 N/m³: 0.7 m).
    pub(super) fn penalty(
        &self,
        field: &str,
        given: Option<f64>,
        mesh: &TetMesh,
        material: &Material,
    ) -> Result<f64, SceneError> {
        let default = stiffness_for_edge(self.mean_boundary_edge(mesh), material.young());
        let Some(k) = given else {
            return Ok(default);
        };
        let k = self.positive(field, k)?;
        let (low, high) = (PENALTY_RANGE.0 * default, PENALTY_RANGE.1 * default);
        if !(low..=high).contains(&k) {
            return Err(self.invalid(
                field,
                format!(
                    "{k:e} N/m³ is outside {low:.3e} … {high:.3e} N/m³ ({:e} … {:e} × the default 10 E / h = {default:.3e} N/m³ for this ice and mesh); leave it out for the default",
                    PENALTY_RANGE.0, PENALTY_RANGE.1
                ),
            ));
        }
        Ok(k)
    }

    /// Refuses a mesh of `tets` tets whose run would need more memory than this machine has
    /// available ([`BYTES_PER_TET`] a tet), naming `field` and what to do (`advice`). A scene
    /// built on the processes' parts needs its share of the tets on each process, and the
    /// processes on one machine share its memory.
    pub(super) fn check_memory(
        &self,
        field: &str,
        tets: u128,
        advice: &str,
    ) -> Result<(), SceneError> {
        let available = available_memory();
        let Some(sharing) = self.sharing.get() else {
            return match available.and_then(|a| memory_short(tets, (1, 1), a)) {
                Some((needed, has)) => Err(self.invalid(
                    field,
                    format!(
                        "{tets} tets would need about {needed:.3e} bytes of memory ({BYTES_PER_TET} bytes a tet) and this machine has {has:.3e} available; {advice}"
                    ),
                )),
                None => Ok(()),
            };
        };
        // Every process takes the same decision, from the fullest machine's share.
        let processes = (sharing.rank_and_size().1, sharing.on_this_machine());
        let share = tets as f64 * BYTES_PER_TET / processes.0 as f64;
        let short = available.and_then(|a| memory_short(tets, processes, a));
        let worst = sharing.largest(short.map_or(0.0, |(needed, has)| needed / has));
        if worst <= 1.0 {
            return Ok(());
        }
        Err(self.invalid(
            field,
            format!(
                "{tets} tets on {} processes would need about {share:.3e} bytes of memory each ({BYTES_PER_TET} bytes a tet), {worst:.1} times what each process has on the fullest machine; {advice}, or use more machines",
                processes.0
            ),
        ))
    }

    /// The ice must start outside every obstacle: a node behind an obstacle's surface by more
    /// than round-off (1e-6 of the mesh's size) would be thrown out by the penalty force in the
    /// first step (a cube 0.5 m under a floor left it at 57 m/s). For a mesh obstacle, nodes
    /// within two element sizes of its surface are checked (a surface that cuts the ice), and
    /// for a closed one also one node of each connected part of the mesh, however deep (a
    /// body wholly inside).
    pub(super) fn check_outside_obstacles(
        &self,
        mesh: &TetMesh,
        obstacles: &[Obstacle],
    ) -> Result<(), SceneError> {
        let (lo, hi) = self.bounding_box(mesh);
        let tolerance = 1e-6 * (hi - lo).norm();
        let (nodes, tets) = self.whole_counts(mesh);
        let extent = hi - lo;
        let element = (extent.x * extent.y * extent.z / tets as f64).cbrt();
        let mut planes = Vec::new();
        for (i, o) in obstacles.iter().enumerate() {
            planes.clear();
            o.planes_into(0.0, &mut planes);
            let depth = |x: &Vector3<f64>| {
                let behind_planes = planes
                    .iter()
                    .map(|p| (p.point - x).dot(&p.normal))
                    .fold(f64::NEG_INFINITY, f64::max);
                let behind_surface = o
                    .surface()
                    .and_then(|s| s.closest(*x, 2.0 * element))
                    .map_or(f64::NEG_INFINITY, |c| -c.gap);
                behind_planes.max(behind_surface)
            };
            // On a part, its owned nodes: each node is counted once over the processes.
            let mut inside: Vec<(f64, usize)> = (mesh.rest.iter().enumerate())
                .filter(|&(k, _)| self.owns_node(k))
                .map(|(k, x)| (depth(x), k))
                .filter(|(d, _)| *d > tolerance)
                .collect();
            if let Some(surface) = o.surface().filter(|s| s.is_closed()) {
                let first = self.first_node_of_each_part(mesh);
                inside.extend(
                    first
                        .iter()
                        .map(|&node| (-surface.signed_distance(mesh.rest[node]), node))
                        .filter(|(d, _)| *d > tolerance),
                );
            }
            let found = self.found_anywhere(inside.len());
            if found > 0 {
                // The deepest, and of equally deep nodes the last.
                let local = inside.iter().copied().max_by(|a, b| a.0.total_cmp(&b.0));
                let (deepest, at) = self.deepest(mesh, local);
                // A mesh far larger than the container it is put in was most likely written
                // in other units.
                let units = match &o.shape {
                    Shape::Container { inner }
                        if (hi - lo).norm() > 10.0 * (inner.max - inner.min).norm() =>
                    {
                        format!(
                            "; the mesh is {:.3e} m across and the container {:.3e} m — if the mesh file is in millimetres, set [mesh] scale = 0.001",
                            (hi - lo).norm(),
                            (inner.max - inner.min).norm()
                        )
                    }
                    Shape::Mesh { surface } if !surface.is_closed() => "; an open surface keeps the ice on the side its triangles' normals point to (right-hand rule): if the ice is meant to be on the other side, reverse the triangles' node order".to_string(),
                    _ => String::new(),
                };
                return Err(self.invalid(
                    &format!("obstacle[{i}]"),
                    format!(
                        "{} of the mesh's {} nodes (at least) start inside this obstacle, the deepest {deepest:.3e} m behind its surface at ({:.4}, {:.4}, {:.4}) m; the ice must start outside every obstacle (move the mesh or the obstacle){units}",
                        found,
                        nodes,
                        at.x,
                        at.y,
                        at.z
                    ),
                ));
            }
        }
        Ok(())
    }

    /// A body far larger or far smaller than the obstacles that hold it was most likely
    /// written in other units: a warning names the scale key. Half-spaces have no size; only
    /// containers and mesh obstacles are compared, by the diagonals of their boxes.
    pub(super) fn check_sizes(&self, mesh: &TetMesh, obstacles: &[Obstacle], scale_key: &str) {
        let (lo, hi) = self.bounding_box(mesh);
        let body = (hi - lo).norm();
        let largest = obstacles
            .iter()
            .filter_map(|o| match &o.shape {
                Shape::Container { inner } => Some((inner.max - inner.min).norm()),
                Shape::Mesh { surface } => {
                    let (lo, hi) = surface.bounds();
                    Some((hi - lo).norm())
                }
                Shape::HalfSpace { .. } => None,
            })
            .fold(None, |m: Option<f64>, d| Some(m.map_or(d, |m| m.max(d))));
        let Some(largest) = largest else {
            return;
        };
        let ratio = body / largest;
        let advice = if ratio > SIZE_RATIO_LIMIT {
            format!("if the mesh file is in millimetres, set {scale_key} = 0.001")
        } else if ratio < 1.0 / SIZE_RATIO_LIMIT.powi(2) {
            "if an obstacle's surface file is in millimetres, set its `scale` = 0.001; if the mesh is in metres and meant to be larger, set the scale of the mesh".to_string()
        } else {
            return;
        };
        self.warnings.borrow_mut().push(format!(
            "the ice is {body:.3e} m across and the largest container or mesh obstacle {largest:.3e} m ({ratio:.3e} times): {advice}"
        ));
    }

    /// The connected parts of a mesh (bodies of a Gmsh file, or boxes) must start apart: a
    /// node of one part inside a tet of another (by more than 1e-9 in barycentric
    /// coordinates), or an element centroid inside or on one, is refused — overlapping bodies are pushed apart by contact in the first
    /// step, or pass through each other.
    pub(super) fn check_parts_apart(&self, field: &str, mesh: &TetMesh) -> Result<(), SceneError> {
        let (part, count) = parts(mesh);
        if count < 2 {
            return Ok(());
        }
        let mut grid = BoxGrid::new(element_size(mesh));
        for (e, t) in mesh.tets.iter().enumerate() {
            let p = t.map(|v| mesh.rest[v]);
            grid.insert(
                &p[0].inf(&p[1]).inf(&p[2]).inf(&p[3]),
                &p[0].sup(&p[1]).sup(&p[2]).sup(&p[3]),
                e as u32,
            );
        }
        // Nodes strictly inside another part's tet (a node on a face of it is touching), and
        // element centroids inside or on one (a thin body's nodes may all lie on the other's
        // faces; a centroid is inside its own part, so on another's face it is an overlap).
        let nodes = mesh.rest.iter().zip(&part).map(|(x, &p)| (*x, p, 1e-9));
        let centroids = mesh.tets.iter().map(|t| {
            let x = t.iter().map(|&v| mesh.rest[v]).sum::<Vector3<f64>>() / 4.0;
            (x, part[t[0]], -1e-12)
        });
        let points = nodes.chain(centroids);
        let mut first = None;
        let mut inside_count = 0;
        for (x, own, margin) in points {
            let mut inside = false;
            grid.overlapping(&x, &x, |e| {
                let t = mesh.tets[e as usize];
                inside =
                    inside || (part[t[0]] != own && inside_by(&x, t.map(|v| mesh.rest[v]), margin));
            });
            if inside {
                inside_count += 1;
                first.get_or_insert(x);
            }
        }
        let Some(x) = first else {
            return Ok(());
        };
        Err(self.invalid(
            field,
            format!(
                "the mesh has {count} separate bodies and {inside_count} of the nodes and element centres of one lie inside another, the first at ({:.4}, {:.4}, {:.4}) m; bodies must start apart",
                x.x, x.y, x.z
            ),
        ))
    }

    /// The boundary faces of `mesh` that touch an obstacle: their centroid within half the
    /// mean boundary edge of an obstacle's surface (a container's floor and walls, a
    /// half-space's plane, a mesh obstacle's triangles), and facing it (normals more than 120°
    /// apart). None is an error for the cooling.
    pub(super) fn faces_touching(
        &self,
        mesh: &TetMesh,
        obstacles: &[Obstacle],
    ) -> Result<Vec<[usize; 3]>, SceneError> {
        let faces = mesh.boundary_faces();
        let reach = 0.5 * mesh.mean_boundary_edge();
        let mut planes = Vec::new();
        for o in obstacles {
            o.planes_into(0.0, &mut planes);
        }
        let touching: Vec<[usize; 3]> = faces
            .iter()
            .map(|f| f.nodes)
            .filter(|f| {
                let [a, b, c] = f.map(|v| mesh.rest[v]);
                let x = (a + b + c) / 3.0;
                let outward = (b - a).cross(&(c - a)).normalize();
                // Near the surface and facing it (a top face near a wall's edge is not).
                let touches = |point: Vector3<f64>, normal: Vector3<f64>| {
                    (x - point).dot(&normal).abs() <= reach && outward.dot(&normal) < -0.5
                };
                planes.iter().any(|p| touches(p.point, p.normal))
                    || obstacles
                        .iter()
                        .filter_map(|o| o.surface())
                        .filter_map(|s| s.closest(x, reach))
                        .any(|q| touches(q.point, q.normal))
            })
            .collect();
        if touching.is_empty() {
            return Err(self.invalid(
                "freezing.cooling",
                format!("\"obstacles\": no boundary face of the mesh is within {reach:.3e} m (half its mean boundary edge) of an obstacle"),
            ));
        }
        Ok(touching)
    }
}

/// A length of the mesh's elements (m): the edge of a cube holding the bounding box's volume
/// over the tet count.
/// How many times larger than its largest sized obstacle a body may be before its units are
/// in doubt (a body in millimetres in a glass in metres is 1 000 times larger; an ice cube
/// dropped into a bath is some 10 times smaller); a body smaller by this squared is in doubt.
const SIZE_RATIO_LIMIT: f64 = 30.0;

fn element_size(mesh: &TetMesh) -> f64 {
    let (lo, hi) = mesh.bounding_box();
    let extent = hi - lo;
    (extent.x * extent.y * extent.z / mesh.num_tets() as f64).cbrt()
}

/// Whether `x` lies inside the tet `p` with every barycentric coordinate above `margin`.
fn inside_by(x: &Vector3<f64>, p: [Vector3<f64>; 4], margin: f64) -> bool {
    let volume = |a: &Vector3<f64>, b: &Vector3<f64>, c: &Vector3<f64>, d: &Vector3<f64>| {
        (b - a).cross(&(c - a)).dot(&(d - a))
    };
    let total = volume(&p[0], &p[1], &p[2], &p[3]);
    if total == 0.0 {
        return false;
    }
    (0..4).all(|k| {
        let mut q = p;
        q[k] = *x;
        volume(&q[0], &q[1], &q[2], &q[3]) / total > margin
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_process_needs_its_share_of_the_tets_and_has_its_share_of_its_machine() {
        // 1e8 tets need 1.3e11 bytes: too much for one 64 GB machine, or for 8 processes on
        // it, but 1.6e10 each on 8 machines of 64 GB with one process each.
        let gb = 1u64 << 30;
        assert!(memory_short(100_000_000, (1, 1), 64 * gb).is_some());
        assert!(memory_short(100_000_000, (8, 8), 64 * gb).is_some());
        assert_eq!(memory_short(100_000_000, (8, 1), 64 * gb), None);
        // On one machine the share changes nothing: N processes need what one does.
        for n in [1, 2, 4, 16] {
            let short = |tets| memory_short(tets, (n, n), 64 * gb).is_some();
            assert!(!short(40_000_000) && short(60_000_000), "{n} processes");
        }
        let (needed, has) = memory_short(100_000_000, (2, 2), 64 * gb).unwrap();
        assert_eq!((needed, has), (6.5e10, 32.0 * gb as f64));
    }
}
