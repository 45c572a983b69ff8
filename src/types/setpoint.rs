//! What the controller sends the platform each tick (ENU, SI units), and which kinds a platform
//! accepts. The MAVLink layer converts these to NED.

use super::Vec3;
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

/// The setpoint kinds a platform accepts; the controller picks its output from these.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct AcceptedSetpoints {
    pub velocity: bool,
    pub position: bool,
}
