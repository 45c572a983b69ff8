//! Platforms: what flies the vehicle (the built-in simulator, or an autopilot over MAVLink).
//!
//! In (from the core, each tick): a [`Setpoint`] and [`PlatformRequest`]s. Out (to the core):
//! [`PlatformStatus`] and estimator [`Measurement`]s. Nothing above this layer knows which
//! platform it flies; the MAVLink implementation lives in `platform::mavlink`.

pub mod mavlink;

use crate::control::{AcceptedSetpoints, Setpoint};
use crate::estimator::Measurement;
use crate::mapping::scan::RangeScan;
use crate::types::PlatformStatus;
use serde::{Deserialize, Serialize};
use std::time::Duration;

/// A one-off request to the platform; the outcome shows up in [`PlatformStatus`]
/// (`armed`, `offboard`, `flight`, `last_error`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", tag = "request")]
pub enum PlatformRequest {
    Arm,
    Disarm,
    /// Follow Kestrel's setpoints (PX4 OFFBOARD, ArduPilot GUIDED).
    StartOffboard,
    /// The autopilot's own takeoff, for platforms that need it (ArduPilot NAV_TAKEOFF).
    Takeoff {
        height_m: f64,
    },
    /// The autopilot's own landing (PX4 AUTO.LAND, ArduPilot LAND).
    Land,
    /// Point the gimbal (FLU body angles).
    PointGimbal {
        pitch_rad: f64,
        yaw_rad: f64,
    },
    TakePhoto,
}

/// What a platform can do; the controller and behaviors adapt to it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Capabilities {
    pub setpoints: AcceptedSetpoints,
    /// Takeoff must go through [`PlatformRequest::Takeoff`] instead of climbing on setpoints.
    pub native_takeoff: bool,
    /// Landing goes through [`PlatformRequest::Land`] (the autopilot's land detector disarms).
    pub native_land: bool,
}

/// Everything the platform reports for one tick.
#[derive(Debug, Clone, Default)]
pub struct PlatformFeedback {
    pub status: PlatformStatus,
    pub measurements: Vec<Measurement>,
    pub scans: Vec<RangeScan>,
    /// Outcomes of requests that completed since the last tick (payload acks, refusals).
    pub request_results: Vec<RequestResult>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RequestResult {
    pub request: PlatformRequest,
    /// `Err` carries the autopilot's own reason.
    pub outcome: Result<(), String>,
}

/// A vehicle the core can fly, driven synchronously by a driver loop.
pub trait Platform: Send {
    fn capabilities(&self) -> Capabilities;
    /// Collects what arrived since the last call. Never blocks.
    fn poll(&mut self, now: Duration) -> PlatformFeedback;
    /// Hands over this tick's outputs. Never blocks; `None` means "nothing to command" (on the
    /// ground and idle): the platform must then not invent a setpoint of its own.
    fn command(&mut self, now: Duration, setpoint: Option<Setpoint>, requests: &[PlatformRequest]);
}
