//! Vehicle state: what the estimator believes plus what the platform reports.

use super::{Pose, Vec3};
use serde::{Deserialize, Serialize};
use std::time::Duration;

/// Which parts of an estimate can be trusted.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Validity {
    pub position: bool,
    pub velocity: bool,
    pub attitude: bool,
}

impl Validity {
    pub const ALL: Self = Self {
        position: true,
        velocity: true,
        attitude: true,
    };
    pub fn all(&self) -> bool {
        self.position && self.velocity && self.attitude
    }
}

/// The estimator's output: pose of `base_link` in the `earth` frame (ENU) and its twist.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct EstimatedState {
    pub stamp: Duration,
    pub pose: Pose,
    pub velocity_enu_mps: Vec3,
    pub angular_velocity_flu_radps: Vec3,
    pub valid: Validity,
    /// Incremented whenever the estimate jumps (estimator reset, autopilot reboot).
    pub reset_counter: u32,
}

/// Flight phase as the autopilot reports it (MAVLink's landed state, Aerostack2's platform states).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FlightStatus {
    #[default]
    Disarmed,
    /// Armed, on the ground.
    Landed,
    TakingOff,
    Flying,
    Landing,
    /// Flight ended by a fault (collision, crash); needs a reset.
    Crashed,
}

impl FlightStatus {
    pub fn is_airborne(self) -> bool {
        matches!(self, Self::TakingOff | Self::Flying | Self::Landing)
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Battery {
    pub voltage_v: f64,
    /// 0..=1; `None` when the platform cannot tell.
    pub remaining_fraction: Option<f64>,
}

#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LinkHealth {
    /// Nothing heard yet.
    #[default]
    Connecting,
    Ok,
    /// Heartbeats stopped; the platform is trying to reconnect.
    Lost,
}

/// What the platform (autopilot or simulator) reports each tick.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct PlatformStatus {
    pub link: LinkHealth,
    pub armed: bool,
    /// True when the autopilot follows Kestrel's setpoints (PX4 OFFBOARD, ArduPilot GUIDED).
    pub offboard: bool,
    pub flight: FlightStatus,
    /// Autopilot mode name as the autopilot calls it (e.g. `OFFBOARD`, `GUIDED`, `SIM`).
    pub mode: String,
    /// True when the autopilot has what it needs to arm and fly offboard.
    pub ready_to_fly: bool,
    pub battery: Option<Battery>,
    /// The autopilot's last refusal or fault, with its own words.
    pub last_error: Option<String>,
    /// Counts autopilot reboots seen; a change means the vehicle restarted.
    pub boot_counter: u32,
    /// Where the autopilot's frames come from and Kestrel's go, when the transport pins one
    /// address (MAVLink `udpin`); `None` otherwise.
    #[serde(default)]
    pub autopilot_address: Option<String>,
    /// How many times another address took that place (each one logged and alerted).
    #[serde(default)]
    pub autopilot_address_changes: u32,
}

/// Everything known about one vehicle at one instant; what the API publishes.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct VehicleState {
    pub drone: String,
    pub estimate: EstimatedState,
    pub platform: PlatformStatus,
}
