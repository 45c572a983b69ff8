//! The one scan type every range sensor is adapted to, and the adapters the platforms use.
//!
//! In: sensor readings (four multi-ranger distances, MAVLink `DISTANCE_SENSOR` fields,
//! `OBSTACLE_DISTANCE` sectors, a planar lidar scan). Out: a [`RangeScan`] in the world ENU
//! frame. Depth rows, point clouds and the binary wire form are in `mapping::scan`.
//!
//! Conventions: beam angles are relative to the sensor x axis, counter-clockwise (FLU);
//! `range_m: None` means "no return within `range_max_m`" (the ray is cleared, no hit).
//! Invalid readings (below the minimum range, NaN, "unknown" codes) are dropped, not turned into
//! `None`, because a dropped beam says nothing while `None` clears free space.

use std::f64::consts::{FRAC_PI_4, PI};

use nalgebra::{Vector2, Vector3};
use serde::{Deserialize, Serialize};

/// Why a scan cannot be used.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("invalid scan: {0}")]
pub struct ScanError(pub String);

/// A planar range scan in the world frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RangeScan {
    /// Sensor position in the world (ENU, metres).
    pub origin_enu_m: Vector3<f64>,
    /// Sensor heading in ENU (0 = +x east, CCW positive).
    pub yaw_rad: f64,
    pub range_min_m: f64,
    pub range_max_m: f64,
    pub beams: Vec<Beam>,
}

/// One beam of a [`RangeScan`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Beam {
    /// Relative to the sensor x axis, CCW (FLU).
    pub angle_rad: f64,
    /// `None` = no return within `range_max_m`.
    pub range_m: Option<f64>,
}

impl RangeScan {
    /// Checks the fields the ray caster relies on.
    pub fn validate(&self) -> Result<(), ScanError> {
        let o = &self.origin_enu_m;
        if !(o.x.is_finite() && o.y.is_finite() && o.z.is_finite() && self.yaw_rad.is_finite()) {
            return Err(ScanError("origin or yaw not finite".into()));
        }
        if let Some(i) = self
            .beams
            .iter()
            .position(|b| !b.angle_rad.is_finite() || b.range_m.is_some_and(|r| !r.is_finite()))
        {
            return Err(ScanError(format!("beam {i}: angle or range not finite")));
        }
        if !(self.range_min_m.is_finite()
            && self.range_max_m.is_finite()
            && self.range_min_m >= 0.0
            && self.range_max_m > self.range_min_m)
        {
            return Err(ScanError(format!(
                "need 0 <= range_min < range_max, got {} and {}",
                self.range_min_m, self.range_max_m
            )));
        }
        Ok(())
    }

    /// Unit vector of a beam in the world ENU xy plane.
    pub fn beam_direction_enu(&self, beam: &Beam) -> Vector2<f64> {
        let (sin, cos) = (self.yaw_rad + beam.angle_rad).sin_cos();
        Vector2::new(cos, sin)
    }
}

/// Turns one reading into a beam: drops invalid values, maps "too far" to `None`.
pub(crate) fn beam(
    angle_rad: f64,
    range_m: f64,
    range_min_m: f64,
    range_max_m: f64,
) -> Option<Beam> {
    if range_m.is_nan() || range_m < range_min_m {
        return None;
    }
    let range_m = (range_m < range_max_m).then_some(range_m);
    Some(Beam { angle_rad, range_m })
}

/// Four-beam multi-ranger (Crazyflie deck): front, left, back, right distances in metres.
/// `None` or a value at/above `range_max_m` means no return; NaN or below `range_min_m` is dropped.
pub fn from_multiranger(
    origin_enu_m: Vector3<f64>,
    yaw_rad: f64,
    front_left_back_right_m: [Option<f64>; 4],
    range_min_m: f64,
    range_max_m: f64,
) -> RangeScan {
    let angles = [0.0, PI / 2.0, PI, -PI / 2.0];
    let beams = angles
        .iter()
        .zip(front_left_back_right_m)
        .filter_map(|(&a, r)| match r {
            None => Some(Beam {
                angle_rad: a,
                range_m: None,
            }),
            Some(r) => beam(a, r, range_min_m, range_max_m),
        })
        .collect();
    RangeScan {
        origin_enu_m,
        yaw_rad,
        range_min_m,
        range_max_m,
        beams,
    }
}

/// One MAVLink `DISTANCE_SENSOR` reading as a beam in the vehicle's FLU frame.
/// `orientation` is `MAV_SENSOR_ORIENTATION`; only the eight horizontal yaw rotations (0..=7,
/// multiples of 45 degrees clockwise in FRD) give a beam. A distance at or above `max_distance_cm`
/// is "no return"; below `min_distance_cm` is dropped.
pub fn beam_from_distance_sensor(
    orientation: u8,
    current_distance_cm: u16,
    min_distance_cm: u16,
    max_distance_cm: u16,
) -> Option<Beam> {
    if orientation > 7 {
        return None;
    }
    let angle_rad = -f64::from(orientation) * FRAC_PI_4;
    beam(
        angle_rad,
        f64::from(current_distance_cm) / 100.0,
        f64::from(min_distance_cm) / 100.0,
        f64::from(max_distance_cm) / 100.0,
    )
}

/// Frame of `OBSTACLE_DISTANCE` sector angles.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum SectorFrame {
    /// `MAV_FRAME_BODY_FRD`: 0 = vehicle forward, clockwise positive.
    BodyFrd,
    /// `MAV_FRAME_LOCAL_NED` (or global): 0 = north, clockwise positive.
    LocalNed,
}

/// The fields of a MAVLink `OBSTACLE_DISTANCE` message this adapter needs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ObstacleSectors<'a> {
    /// Usually 72 sectors. `u16::MAX` = unknown (dropped); `> max_distance_cm` = no obstacle.
    pub distances_cm: &'a [u16],
    /// Angular width of a sector: `increment_f` if non-zero, else `increment`.
    pub increment_deg: f64,
    /// Angle of sector 0, clockwise positive.
    pub angle_offset_deg: f64,
    pub min_distance_cm: u16,
    pub max_distance_cm: u16,
    pub frame: SectorFrame,
}

/// `OBSTACLE_DISTANCE` sectors to a scan. `vehicle_yaw_enu_rad` is used for body-frame sectors.
pub fn from_obstacle_distance(
    origin_enu_m: Vector3<f64>,
    vehicle_yaw_enu_rad: f64,
    sectors: &ObstacleSectors<'_>,
) -> RangeScan {
    let range_min_m = f64::from(sectors.min_distance_cm) / 100.0;
    let range_max_m = f64::from(sectors.max_distance_cm) / 100.0;
    let (yaw_rad, to_flu): (f64, fn(f64) -> f64) = match sectors.frame {
        // FRD clockwise -> FLU counter-clockwise.
        SectorFrame::BodyFrd => (vehicle_yaw_enu_rad, |a| -a),
        // North clockwise -> ENU: east = 0, counter-clockwise.
        SectorFrame::LocalNed => (0.0, |a| PI / 2.0 - a),
    };
    let beams = sectors
        .distances_cm
        .iter()
        .enumerate()
        .filter(|(_, &d)| d != u16::MAX)
        .filter_map(|(i, &d)| {
            let a_deg = sectors.angle_offset_deg + sectors.increment_deg * i as f64;
            let angle = to_flu(a_deg.to_radians());
            if d > sectors.max_distance_cm {
                Some(Beam {
                    angle_rad: angle,
                    range_m: None,
                })
            } else {
                beam(angle, f64::from(d) / 100.0, range_min_m, range_max_m)
            }
        })
        .collect();
    RangeScan {
        origin_enu_m,
        yaw_rad,
        range_min_m,
        range_max_m,
        beams,
    }
}

/// A planar lidar scan (ROS `LaserScan` layout): `ranges_m[i]` at `angle_min + i * increment`.
/// NaN and values below `range_min_m` are dropped; `+inf` and values above `range_max_m` are
/// "no return".
pub fn from_planar_lidar(
    origin_enu_m: Vector3<f64>,
    yaw_rad: f64,
    angle_min_rad: f64,
    angle_increment_rad: f64,
    ranges_m: &[f64],
    range_min_m: f64,
    range_max_m: f64,
) -> RangeScan {
    let beams = ranges_m
        .iter()
        .enumerate()
        .filter_map(|(i, &r)| {
            beam(
                angle_min_rad + angle_increment_rad * i as f64,
                r,
                range_min_m,
                range_max_m,
            )
        })
        .collect();
    RangeScan {
        origin_enu_m,
        yaw_rad,
        range_min_m,
        range_max_m,
        beams,
    }
}
