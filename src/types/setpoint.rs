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
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct AcceptedSetpoints {
    pub velocity: bool,
    pub position: bool,
    /// `Some` when the platform closes the position loop itself and should be given a moving
    /// reference point with its velocity as feed-forward (PX4 and ArduPilot): the autopilot's
    /// own tuned loop then holds the vehicle on it. `None`: Kestrel closes the loop over
    /// velocity setpoints.
    pub position_loop: Option<PositionLoop>,
}

/// The position loop an autopilot closes on a position setpoint with feed-forward:
/// `v_cmd = v_ff + gain * (p_sp - p)`. Kestrel needs the gains to keep `v_cmd` within the
/// speed limits (PX4: `MPC_XY_P`, `MPC_Z_P`; ArduPilot: `PSC_POSXY_P`, `PSC_POSZ_P`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PositionLoop {
    pub gain_xy_per_s: f64,
    pub gain_z_per_s: f64,
}

impl PositionLoop {
    /// The velocity the autopilot commands for a position error (ENU, m -> m/s).
    pub fn correction(&self, error_enu_m: Vec3) -> Vec3 {
        Vec3::new(
            error_enu_m.x * self.gain_xy_per_s,
            error_enu_m.y * self.gain_xy_per_s,
            error_enu_m.z * self.gain_z_per_s,
        )
    }
}

impl Setpoint {
    /// The same setpoint with `offset_enu_mps` added to its velocity (a position target's
    /// feed-forward): what an autopilot whose velocity estimate is off by that much must hear.
    pub fn with_velocity_added(self, offset_enu_mps: Vec3) -> Self {
        match self {
            Setpoint::Velocity {
                velocity_enu_mps,
                yaw,
            } => Setpoint::Velocity {
                velocity_enu_mps: velocity_enu_mps + offset_enu_mps,
                yaw,
            },
            Setpoint::Position {
                position_enu_m,
                velocity_ff_enu_mps,
                yaw,
            } => Setpoint::Position {
                position_enu_m,
                velocity_ff_enu_mps: velocity_ff_enu_mps + offset_enu_mps,
                yaw,
            },
        }
    }
}
