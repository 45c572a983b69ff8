//! NED/FRD (MAVLink) ↔ ENU/FLU (Kestrel) conversions: the only place the two meet.
//!
//! In: MAVLink vectors (north, east, down), headings (from north, clockwise), body rates and
//! attitude quaternions in FRD. Out: ENU vectors, ENU headings (from east, counter-clockwise),
//! FLU rates and attitudes; and the reverse for setpoints.

use crate::types::{wrap_angle_rad, Vec3};
use nalgebra::{Quaternion, UnitQuaternion};
use std::f64::consts::FRAC_PI_2;

/// A NED vector (m or m/s) to ENU: x_enu = y_ned, y_enu = x_ned, z_enu = -z_ned.
pub fn ned_to_enu(north: f64, east: f64, down: f64) -> Vec3 {
    Vec3::new(east, north, -down)
}

/// An ENU vector to NED `[north, east, down]`.
pub fn enu_to_ned(v: &Vec3) -> [f64; 3] {
    [v.y, v.x, -v.z]
}

/// A heading from north, clockwise (NED yaw) to ENU yaw (from east, counter-clockwise).
pub fn yaw_ned_to_enu(yaw_ned_rad: f64) -> f64 {
    wrap_angle_rad(FRAC_PI_2 - yaw_ned_rad)
}

/// ENU yaw to NED yaw; the map is its own inverse.
pub fn yaw_enu_to_ned(yaw_enu_rad: f64) -> f64 {
    wrap_angle_rad(FRAC_PI_2 - yaw_enu_rad)
}

/// FRD body rates (roll, pitch, yaw rate) to FLU: y and z flip.
pub fn frd_to_flu(x: f64, y: f64, z: f64) -> Vec3 {
    Vec3::new(x, -y, -z)
}

/// Rotation taking NED coordinates to ENU (180° about the (1, 1, 0) axis).
fn enu_from_ned() -> UnitQuaternion<f64> {
    let s = std::f64::consts::FRAC_1_SQRT_2;
    UnitQuaternion::from_quaternion(Quaternion::new(0.0, s, s, 0.0))
}

/// Rotation taking FLU coordinates to FRD (180° about x); its own inverse.
fn frd_from_flu() -> UnitQuaternion<f64> {
    UnitQuaternion::from_quaternion(Quaternion::new(0.0, 1.0, 0.0, 0.0))
}

/// The attitude of a body (FRD → NED) as Kestrel's FLU → ENU attitude.
pub fn attitude_ned_frd_to_enu_flu(q_ned_frd: &UnitQuaternion<f64>) -> UnitQuaternion<f64> {
    enu_from_ned() * q_ned_frd * frd_from_flu()
}

/// ATTITUDE's Euler angles (roll, pitch, yaw of FRD in NED, ZYX order) as an FLU → ENU attitude.
pub fn attitude_from_euler_ned(roll_rad: f64, pitch_rad: f64, yaw_rad: f64) -> UnitQuaternion<f64> {
    attitude_ned_frd_to_enu_flu(&UnitQuaternion::from_euler_angles(
        roll_rad, pitch_rad, yaw_rad,
    ))
}

/// A MAVLink quaternion `[w, x, y, z]` (FRD → NED) as an FLU → ENU attitude; `None` when it is
/// not finite or not close to unit length.
pub fn attitude_from_mav_quaternion(q: [f32; 4]) -> Option<UnitQuaternion<f64>> {
    let [w, x, y, z] = q.map(f64::from);
    let raw = Quaternion::new(w, x, y, z);
    let n = raw.norm();
    if !n.is_finite() || (n - 1.0).abs() > 0.1 {
        return None;
    }
    Some(attitude_ned_frd_to_enu_flu(
        &UnitQuaternion::from_quaternion(raw),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    #[test]
    fn vectors_swap_and_flip() {
        let v = ned_to_enu(1.0, 2.0, -3.0);
        assert_eq!(v, Vec3::new(2.0, 1.0, 3.0));
        assert_eq!(enu_to_ned(&v), [1.0, 2.0, -3.0]);
    }

    #[test]
    fn headings_map_north_to_ninety_degrees() {
        assert!((yaw_ned_to_enu(0.0) - FRAC_PI_2).abs() < 1e-12);
        assert!((yaw_ned_to_enu(FRAC_PI_2) - 0.0).abs() < 1e-12);
        assert!((yaw_ned_to_enu(PI) + FRAC_PI_2).abs() < 1e-12);
        for y in [-3.0, -1.0, 0.3, 2.5] {
            assert!((yaw_ned_to_enu(yaw_enu_to_ned(y)) - y).abs() < 1e-12);
        }
    }

    #[test]
    fn attitude_keeps_heading_and_flips_tilt_axes() {
        // Facing east in NED (yaw 90°) is ENU yaw 0.
        let q = attitude_from_euler_ned(0.0, 0.0, FRAC_PI_2);
        let (r, p, y) = q.euler_angles();
        assert!(
            r.abs() < 1e-9 && p.abs() < 1e-9 && y.abs() < 1e-9,
            "{r} {p} {y}"
        );
        // Nose up in FRD (positive pitch) is nose up in FLU too: the body x axis points up.
        let q = attitude_from_euler_ned(0.0, 0.3, 0.0);
        let nose = q * Vec3::x();
        assert!(nose.z > 0.29, "{nose}");
        // Right wing down in FRD (positive roll): the FLU left axis (y) points up.
        let q = attitude_from_euler_ned(0.2, 0.0, 0.0);
        let left = q * Vec3::y();
        assert!(left.z > 0.19, "{left}");
    }

    #[test]
    fn quaternion_and_euler_agree() {
        let e = UnitQuaternion::from_euler_angles(0.1, -0.2, 2.0);
        let q = [e.w as f32, e.i as f32, e.j as f32, e.k as f32];
        let a = attitude_from_mav_quaternion(q).unwrap();
        let b = attitude_from_euler_ned(0.1, -0.2, 2.0);
        assert!(a.angle_to(&b) < 1e-6);
        assert!(attitude_from_mav_quaternion([0.0, 0.0, 0.0, 0.0]).is_none());
        assert!(attitude_from_mav_quaternion([f32::NAN, 0.0, 0.0, 0.0]).is_none());
    }
}
