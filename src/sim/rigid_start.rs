//! Newton's start for a dynamic solve where a part of the mesh turns: the part carried
//! rigidly to where the scheme's predictor puts it, instead of the predictor itself.
//!
//! A predictor moves each node along a straight line (ũ = uₙ + h vₙ for backward Euler). For
//! a turning part that line leaves the rotation: the part comes out stretched by ~(hω)², and
//! ice stores that stretch at ~1e10 Pa. The step's potential is then a narrow curved valley
//! (the rotations, along which only inertia resists) in a steep elastic bowl; Newton from the
//! predictor follows the valley with damped steps and needs 13–16 iterations per step for a
//! 4 cm cube turning at 10 rad/s at h = 1/600 s. The rigid motion of the start shape closest
//! to the predictor in the mass norm — the predictor's centre of mass and the rotation R that
//! minimises Σ mᵢ |R (xᵢ − c) − (x̃ᵢ − c̃)|² (Kabsch) — is the stiff limit of the step's
//! solution, so Newton started there has only the elastic response left to solve for. The
//! solution does not depend on where Newton starts; the solve takes the start of lower
//! potential.
//!
//! Only a part that turns by more than the width of that valley is started rigidly: Newton's
//! quadratic model of the step holds along a rotation by θ while the elastic energy of the
//! stretch, ~K L² θ⁴, stays below the inertia's, ~M L² θ²/h², i.e. for
//! θ < w = √(M / (h² K)) with K ≈ E L (E Young's modulus, L the part's radius of gyration, M
//! its mass). w is 3.6e-3 rad for the 4 cm cube at h = 1/600 s (it turns by 1.7e-2); a body
//! at rest turns by round-off, far below, and keeps the predictor.

use crate::mesh::parts::parts_of;
use crate::mesh::TetMesh;
use nalgebra::{Matrix3, Vector3};

/// The parts of a mesh that move freely (none of their nodes supported).
#[derive(Clone, Debug, Default)]
pub(super) struct RigidStart {
    /// Part of each node; `u32::MAX` for the nodes of parts with a supported node.
    part: Vec<u32>,
    /// Number of parts (supported ones included).
    count: usize,
}

impl RigidStart {
    /// The free parts of `mesh` given its constrained dofs (3 per node).
    pub(super) fn new(mesh: &TetMesh, constrained: &[bool]) -> Self {
        let (mut part, count) = parts_of(mesh.num_nodes(), &mesh.tets);
        let mut supported = vec![false; count];
        for (i, &p) in part.iter().enumerate() {
            if constrained[3 * i..3 * i + 3].iter().any(|&c| c) {
                supported[p as usize] = true;
            }
        }
        for p in &mut part {
            if supported[*p as usize] {
                *p = u32::MAX;
            }
        }
        RigidStart { part, count }
    }

    /// Newton's start (displacements, m, 3 per node) with every free part that turns by more
    /// than its valley's width (see the module docs) moved rigidly from its shape at the start
    /// `u` (m) to the predictor `predictor` (m), and every other node at the predictor; `None`
    /// if no part turns that much. `rest` are the rest positions (m), `mass` the nodal masses
    /// (kg), `h` the solve's step (s) and `young` the ice's Young's modulus (Pa).
    pub(super) fn start(
        &self,
        rest: &[Vector3<f64>],
        (u, predictor): (&[f64], &[f64]),
        mass: &[f64],
        (h, young): (f64, f64),
    ) -> Option<Vec<f64>> {
        let at = |d: &[f64], i: usize| rest[i] + Vector3::new(d[3 * i], d[3 * i + 1], d[3 * i + 2]);
        let free = || self.part.iter().enumerate().filter(|(_, &p)| p != u32::MAX);
        let mut total = vec![0.0; self.count];
        let mut centre = vec![(Vector3::zeros(), Vector3::zeros()); self.count];
        for (i, &p) in free() {
            let p = p as usize;
            total[p] += mass[i];
            centre[p].0 += mass[i] * at(u, i);
            centre[p].1 += mass[i] * at(predictor, i);
        }
        for (c, &m) in centre.iter_mut().zip(&total) {
            if m > 0.0 {
                *c = (c.0 / m, c.1 / m);
            }
        }
        let mut covariance = vec![Matrix3::zeros(); self.count];
        let mut second_moment = vec![0.0; self.count];
        for (i, &p) in free() {
            let (c, c_pred) = centre[p as usize];
            let r = at(u, i) - c;
            covariance[p as usize] += mass[i] * (at(predictor, i) - c_pred) * r.transpose();
            second_moment[p as usize] += mass[i] * r.norm_squared();
        }
        let rotation: Vec<Option<Matrix3<f64>>> = (0..self.count)
            .map(|p| {
                let gyration = (second_moment[p] / total[p]).sqrt();
                let width = (total[p] / (h * h * young * gyration)).sqrt();
                turn(&covariance[p]).filter(|r| angle(r) > width)
            })
            .collect();
        if rotation.iter().all(Option::is_none) {
            return None;
        }
        let mut start = predictor.to_vec();
        for (i, &p) in free() {
            if let Some(r) = &rotation[p as usize] {
                let (c, c_pred) = centre[p as usize];
                let x = c_pred + r * (at(u, i) - c) - rest[i];
                start[3 * i..3 * i + 3].copy_from_slice(x.as_slice());
            }
        }
        Some(start)
    }
}

/// The rotation R maximising tr(Rᵀ A) (the polar factor of A with det R = +1); `None` if A
/// is degenerate (a part whose nodes lie in a plane or on a line).
fn turn(a: &Matrix3<f64>) -> Option<Matrix3<f64>> {
    let svd = a.svd(true, true);
    let (u, v_t) = (svd.u?, svd.v_t?);
    // NaN singular values (a part with non-finite positions) count as degenerate too.
    let smallest = svd.singular_values.min();
    let degenerate = smallest.is_nan() || smallest <= 1e-12 * svd.singular_values.max();
    if degenerate {
        return None;
    }
    let mut flip = Matrix3::identity();
    flip[(2, 2)] = (u * v_t).determinant().signum();
    // nalgebra sorts the singular values in decreasing order: the flip takes the smallest.
    Some(u * flip * v_t)
}

/// The angle of the rotation `r` (rad), from its skew part (accurate for small angles).
fn angle(r: &Matrix3<f64>) -> f64 {
    let w = Vector3::new(
        r[(2, 1)] - r[(1, 2)],
        r[(0, 2)] - r[(2, 0)],
        r[(1, 0)] - r[(0, 1)],
    );
    (0.5 * w.norm()).atan2(0.5 * (r.trace() - 1.0))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::generate::box_mesh;
    use nalgebra::Rotation3;

    /// Displacements (3 per node) moving the box's rest positions by `map` about their centre,
    /// then by `shift`.
    fn moved(rest: &[Vector3<f64>], map: &Matrix3<f64>, shift: Vector3<f64>) -> Vec<f64> {
        let centre = rest.iter().sum::<Vector3<f64>>() / rest.len() as f64;
        rest.iter()
            .flat_map(|x| {
                let y = centre + shift + map * (x - centre) - x;
                [y.x, y.y, y.z]
            })
            .collect()
    }

    /// Step (s) and Young's modulus (Pa) of a stiff body: unit masses on ~1 m boxes give a
    /// rotation valley √(M / (h² E L)) of ~7e-3 rad, well below the turns of the tests.
    const STIFF: (f64, f64) = (1.0, 1e6);

    /// Largest absolute difference of two vectors.
    fn max_diff(a: &[f64], b: &[f64]) -> f64 {
        a.iter()
            .zip(b)
            .map(|(x, y)| (x - y).abs())
            .fold(0.0, f64::max)
    }

    /// A cube turning at ω about a skew axis: the predictor of a step h moves it by
    /// I + h[ω]ₓ, which stretches it; the start turns it by exp(h[ω]ₓ) up to the polar
    /// factor's third-order difference, and keeps its shape exactly.
    #[test]
    fn turns_the_start_shape_instead_of_stretching_it() {
        let mesh = box_mesh([0.0; 3], [1.0; 3], [2, 2, 2], 6).unwrap();
        let (rest, n) = (&mesh.rest, mesh.num_nodes());
        let turn = Vector3::new(0.03, -0.08, 0.05); // h ω (rad)
        let shift = Vector3::new(0.2, -0.1, 0.3);
        let predictor = moved(rest, &(Matrix3::identity() + turn.cross_matrix()), shift);
        let rotated = moved(rest, Rotation3::new(turn).matrix(), shift);
        let start = RigidStart::new(&mesh, &vec![false; 3 * n]);
        let zero = vec![0.0; 3 * n];
        let guess =
            (start.start(rest, (&zero, &predictor), &vec![1.0; n], STIFF)).expect("it turns");
        // For a cube (isotropic second moment) the fit is the polar factor of I + h[ω]ₓ, the
        // rotation by atan|hω| about ω: |hω|³/3 ≈ 3.3e-4 rad from exp(h[ω]ₓ), times the
        // cube's half-diagonal 0.87 m.
        assert!(
            max_diff(&guess, &rotated) < 3.5e-4 * 0.87,
            "{}",
            max_diff(&guess, &rotated)
        );
        // The predictor is ½|hω|² ≈ 4.9e-3 of a node's distance from the axis (≤ 0.87 m) off; the start
        // keeps every edge length.
        assert!(max_diff(&predictor, &rotated) > 2e-3);
        for t in &mesh.tets {
            let x =
                |i: usize| rest[i] + Vector3::new(guess[3 * i], guess[3 * i + 1], guess[3 * i + 2]);
            for (a, b) in [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)] {
                let (l0, l) = ((rest[t[a]] - rest[t[b]]).norm(), (x(t[a]) - x(t[b])).norm());
                assert!((l - l0).abs() < 1e-14, "{l} vs {l0}");
            }
        }
        // A supported part keeps the predictor: nothing turns freely.
        let mut constrained = vec![false; 3 * n];
        constrained[0] = true;
        let held = RigidStart::new(&mesh, &constrained);
        assert!(held
            .start(rest, (&zero, &predictor), &vec![1.0; n], STIFF)
            .is_none());
        // A part at rest keeps it too, and so does one whose turn is within the valley of a
        // soft material (E = 1 Pa: a valley of ~7 rad).
        assert!(start
            .start(rest, (&zero, &zero), &vec![1.0; n], STIFF)
            .is_none());
        assert!(start
            .start(rest, (&zero, &predictor), &vec![1.0; n], (1.0, 1.0))
            .is_none());
    }

    /// On an elongated box with unequal masses the start is the rigid motion closest to the
    /// predictor in the mass norm: turning it further by ±1e-4 rad about any axis moves it
    /// away from the predictor.
    #[test]
    fn is_the_closest_rigid_motion_in_the_mass_norm() {
        let mesh = box_mesh([0.0; 3], [1.0, 2.0, 0.5], [2, 3, 2], 6).unwrap();
        let (rest, n) = (&mesh.rest, mesh.num_nodes());
        let mass: Vec<f64> = (0..n).map(|i| 1.0 + (i % 5) as f64).collect();
        let map = Matrix3::identity() + Vector3::new(0.1, 0.05, -0.2).cross_matrix();
        let predictor = moved(rest, &map, Vector3::new(0.1, 0.2, 0.3));
        let zero = vec![0.0; 3 * n];
        let start = RigidStart::new(&mesh, &vec![false; 3 * n]);
        let guess = start
            .start(rest, (&zero, &predictor), &mass, STIFF)
            .expect("it turns");
        let distance = |u: &[f64]| -> f64 {
            (0..3 * n)
                .map(|d| mass[d / 3] * (u[d] - predictor[d]).powi(2))
                .sum()
        };
        let centre: Vector3<f64> = (0..n)
            .map(|i| {
                mass[i] * (rest[i] + Vector3::new(guess[3 * i], guess[3 * i + 1], guess[3 * i + 2]))
            })
            .sum::<Vector3<f64>>()
            / mass.iter().sum::<f64>();
        let best = distance(&guess);
        for axis in [Vector3::x(), Vector3::y(), Vector3::z()] {
            for sign in [-1.0, 1.0] {
                let r = Rotation3::new(axis * (sign * 1e-4));
                let turned: Vec<f64> = (0..n)
                    .flat_map(|i| {
                        let x = rest[i]
                            + Vector3::new(guess[3 * i], guess[3 * i + 1], guess[3 * i + 2]);
                        let y = centre + r * (x - centre) - rest[i];
                        [y.x, y.y, y.z]
                    })
                    .collect();
                assert!(distance(&turned) > best, "{} ≤ {best}", distance(&turned));
            }
        }
    }
}
