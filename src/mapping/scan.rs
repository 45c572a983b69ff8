//! One scan type every range sensor is adapted to.

use nalgebra::Vector3;

/// A planar range scan taken at one instant.
#[derive(Debug, Clone, PartialEq)]
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
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Beam {
    /// Relative to the sensor x axis, CCW (FLU).
    pub angle_rad: f64,
    /// `None` = no return within `range_max_m`.
    pub range_m: Option<f64>,
}
