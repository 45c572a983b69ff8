//! Geometry primitives: vectors and poses in metres and radians.

use nalgebra::{Isometry3, Translation3, UnitQuaternion};
use serde::{Deserialize, Serialize};

/// A 3-D vector; its frame and unit are given by the name of the field holding it.
pub type Vec3 = nalgebra::Vector3<f64>;
/// A 2-D vector (horizontal ENU plane unless the field says otherwise).
pub type Vec2 = nalgebra::Vector2<f64>;

/// Wraps an angle to (-pi, pi].
pub fn wrap_angle_rad(angle_rad: f64) -> f64 {
    let two_pi = std::f64::consts::TAU;
    let mut a = angle_rad.rem_euclid(two_pi);
    if a > std::f64::consts::PI {
        a -= two_pi;
    }
    a
}

/// Position and orientation of a body in some frame.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Pose {
    pub position_m: Vec3,
    pub orientation: UnitQuaternion<f64>,
}

impl Default for Pose {
    fn default() -> Self {
        Self::identity()
    }
}

impl Pose {
    pub fn identity() -> Self {
        Self {
            position_m: Vec3::zeros(),
            orientation: UnitQuaternion::identity(),
        }
    }

    /// A pose with only a heading (multirotor-style: roll and pitch zero).
    pub fn from_position_yaw(position_m: Vec3, yaw_rad: f64) -> Self {
        Self {
            position_m,
            orientation: UnitQuaternion::from_euler_angles(0.0, 0.0, yaw_rad),
        }
    }

    pub fn yaw_rad(&self) -> f64 {
        self.orientation.euler_angles().2
    }

    pub fn to_isometry(&self) -> Isometry3<f64> {
        Isometry3::from_parts(Translation3::from(self.position_m), self.orientation)
    }

    pub fn from_isometry(iso: &Isometry3<f64>) -> Self {
        Self {
            position_m: iso.translation.vector,
            orientation: iso.rotation,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    #[test]
    fn wrap_angle_stays_in_half_open_interval() {
        assert!((wrap_angle_rad(3.0 * PI) - PI).abs() < 1e-12);
        assert!((wrap_angle_rad(-PI) - PI).abs() < 1e-12);
        assert!((wrap_angle_rad(-0.5) + 0.5).abs() < 1e-12);
        assert!((wrap_angle_rad(2.0 * PI + 0.25) - 0.25).abs() < 1e-12);
    }

    #[test]
    fn pose_yaw_round_trips() {
        let p = Pose::from_position_yaw(Vec3::new(1.0, 2.0, 3.0), 1.2);
        assert!((p.yaw_rad() - 1.2).abs() < 1e-12);
        let back = Pose::from_isometry(&p.to_isometry());
        assert!((back.position_m - p.position_m).norm() < 1e-12);
    }
}
