//! What behaviors ask of the controller, and what the controller asks of the platform.

use crate::types::Vec3;
use serde::{Deserialize, Serialize};

/// Heading part of a reference or setpoint.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum YawTarget {
    /// Hold this heading (ENU, rad, 0 = east, CCW positive).
    Angle(f64),
    /// Turn at this rate (rad/s, CCW positive).
    Rate(f64),
}

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
    /// Track a moving reference point with feed-forward velocity and acceleration.
    Trajectory {
        position_enu_m: Vec3,
        velocity_enu_mps: Vec3,
        acceleration_enu_mps2: Vec3,
        yaw: YawTarget,
    },
}

/// The command sent to the platform each tick (ENU; the MAVLink layer converts to NED).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", tag = "kind")]
pub enum Setpoint {
    Velocity {
        velocity_enu_mps: Vec3,
        yaw: YawTarget,
    },
    Position {
        position_enu_m: Vec3,
        velocity_ff_enu_mps: Vec3,
        yaw: YawTarget,
    },
}

impl MotionReference {
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

/// The setpoint kinds a platform accepts; the controller picks its output from these.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct AcceptedSetpoints {
    pub velocity: bool,
    pub position: bool,
}
