//! Rigid motion of an obstacle: a translation and a rotation about a point, both scaled in time
//! by one amplitude.

use super::Amplitude;
use nalgebra::{Rotation3, Vector3};

/// How an obstacle moves: a point X of it at t = 0 is at x(t) = c(t) + R(t)(X − c), with the
/// centre c(t) = c + v A(t), R(t) the rotation by the vector ω A(t) and A(t) = ∫₀ᵗ a(s) ds the
/// integral of the amplitude (A(t) = t when the amplitude is 1). Its velocity at x is
/// a(t) (v + ω × (x − c(t))).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Motion {
    /// Velocity v at amplitude 1 (m/s).
    pub velocity: Vector3<f64>,
    /// Angular velocity ω at amplitude 1 (rad/s), about `centre`.
    pub angular_velocity: Vector3<f64>,
    /// Point c the rotation is about, at t = 0 (m); it moves with the velocity.
    pub centre: Vector3<f64>,
    /// Amplitude a(t) of both velocities.
    pub amplitude: Amplitude,
}

impl Motion {
    /// A constant velocity `v` (m/s).
    pub fn translating(velocity: Vector3<f64>) -> Self {
        Motion {
            velocity,
            ..Default::default()
        }
    }

    /// Whether the obstacle turns.
    pub fn rotates(&self) -> bool {
        self.angular_velocity != Vector3::zeros()
    }

    /// The rotation R(t) and the centre c(t) (m) at time `t` (s).
    pub fn placement(&self, t: f64) -> (Rotation3<f64>, Vector3<f64>) {
        let travelled = self.amplitude.integral(t);
        (
            Rotation3::new(self.angular_velocity * travelled),
            self.centre + self.velocity * travelled,
        )
    }

    /// Where the point `x0` of the obstacle at t = 0 is at time `t` (m).
    pub fn position(&self, t: f64, x0: &Vector3<f64>) -> Vector3<f64> {
        let (rotation, centre) = self.placement(t);
        centre + rotation * (x0 - self.centre)
    }

    /// The point of the obstacle at t = 0 that is at `x` at time `t` (m).
    pub fn origin_of(&self, t: f64, x: &Vector3<f64>) -> Vector3<f64> {
        let (rotation, centre) = self.placement(t);
        self.centre + rotation.inverse() * (x - centre)
    }

    /// The velocity (m/s) at time `t` of the obstacle's point at `x`.
    pub fn velocity_at(&self, t: f64, x: &Vector3<f64>) -> Vector3<f64> {
        let (_, centre) = self.placement(t);
        self.amplitude.at(t) * (self.velocity + self.angular_velocity.cross(&(x - centre)))
    }

    /// The largest speed (m/s) of a point within `radius` (m) of the centre: an upper bound
    /// over the amplitude's values.
    pub fn speed_bound(&self, radius: f64) -> f64 {
        self.amplitude.max_abs() * (self.velocity.norm() + self.angular_velocity.norm() * radius)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_turning_moving_obstacle_carries_its_points_rigidly() {
        let motion = Motion {
            velocity: Vector3::new(1.0, 0.0, 0.0),
            angular_velocity: Vector3::new(0.0, 0.0, std::f64::consts::PI),
            centre: Vector3::new(0.0, 1.0, 0.0),
            amplitude: Amplitude::new(vec![(0.0, 1.0), (1.0, 1.0), (1.0, 0.0)]).unwrap(),
        };
        // After 1 s: half a turn about the centre, which moved 1 m along x; then it stops.
        let x0 = Vector3::new(1.0, 1.0, 0.5);
        let x1 = motion.position(1.0, &x0);
        assert!((x1 - Vector3::new(0.0, 1.0, 0.5)).norm() < 1e-15, "{x1}");
        assert_eq!(motion.position(3.0, &x0), x1, "stopped");
        assert!((motion.origin_of(1.0, &x1) - x0).norm() < 1e-15);
        // Velocity at 0.5 s of the point then at x: v + ω × (x − c(0.5)).
        let x = motion.position(0.5, &x0);
        let v = motion.velocity_at(0.5, &x);
        let h = 1e-6;
        let fd = (motion.position(0.5 + h, &x0) - motion.position(0.5 - h, &x0)) / (2.0 * h);
        assert!((v - fd).norm() < 1e-8, "{v} vs {fd}");
        assert_eq!(motion.velocity_at(2.0, &x), Vector3::zeros());
    }
}
