//! What behaviors ask of the controller (the setpoint vocabulary it answers with is in `types`).

use crate::types::Vec3;
pub use crate::types::{AcceptedSetpoints, Setpoint, YawTarget};
use serde::{Deserialize, Serialize};

/// A motion reference in the `earth` frame, produced by a behavior each tick.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", tag = "mode")]
pub enum MotionReference {
    /// Go to and hold a position, approaching not faster than `max_speed_mps`; the target's own
    /// velocity (a point in a moving frame) is added as feed-forward.
    Position {
        position_enu_m: Vec3,
        velocity_ff_enu_mps: Vec3,
        yaw: YawTarget,
        max_speed_mps: f64,
    },
    /// Fly this velocity.
    Velocity {
        velocity_enu_mps: Vec3,
        yaw: YawTarget,
    },
    /// Track a moving reference point with feed-forward velocity and acceleration, never
    /// commanding more than `max_speed_mps` (the correction toward the point included).
    Trajectory {
        position_enu_m: Vec3,
        velocity_enu_mps: Vec3,
        acceleration_enu_mps2: Vec3,
        yaw: YawTarget,
        max_speed_mps: f64,
    },
}

impl MotionReference {
    /// The speed the commanded velocity must stay within (m/s); a velocity reference is
    /// limited by the vehicle's limits alone.
    pub fn max_speed_mps(&self) -> f64 {
        match self {
            Self::Position { max_speed_mps, .. } | Self::Trajectory { max_speed_mps, .. } => {
                *max_speed_mps
            }
            Self::Velocity { .. } => f64::INFINITY,
        }
    }

    /// The point the reference holds the vehicle at, or tracks it along (`None` for a
    /// velocity).
    pub fn held_at(&self) -> Option<Vec3> {
        match self {
            Self::Position { position_enu_m, .. } | Self::Trajectory { position_enu_m, .. } => {
                Some(*position_enu_m)
            }
            Self::Velocity { .. } => None,
        }
    }

    /// Hold `position_enu_m` with heading `yaw_rad`.
    pub fn hold(position_enu_m: Vec3, yaw_rad: f64, max_speed_mps: f64) -> Self {
        Self::Position {
            position_enu_m,
            velocity_ff_enu_mps: Vec3::zeros(),
            yaw: YawTarget::Angle(yaw_rad),
            max_speed_mps,
        }
    }
}
