//! What the core and a platform exchange each tick, besides the setpoint: one-off requests and
//! their outcomes, the platform's capabilities, and everything it reports (status,
//! measurements, scans).

use super::measurement::Measurement;
use super::scan::RangeScan;
use super::setpoint::AcceptedSetpoints;
use super::PlatformStatus;
use serde::{Deserialize, Serialize};

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
    /// Kestrel is flying the vehicle down to touchdown on its own setpoints (platforms without
    /// `native_land`), repeated every tick of the landing: the autopilot's land mode or its
    /// disarm meanwhile end Kestrel's landing, they are not a pilot taking over.
    LandOnSetpoints,
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
    /// Time constant of the autopilot's velocity response (s), when the profile knows it; the
    /// config's `[controller] velocity_lag_s` overrides it.
    pub velocity_lag_s: Option<f64>,
    /// How much faster than a velocity it is sent the vehicle may fly, as a fraction (0.15: up
    /// to 15 % faster), when the profile knows it. Kestrel plans and commands within each speed
    /// limit divided by one plus it, so the flown speed holds the limit. The config's
    /// `[controller] velocity_overshoot` overrides it.
    pub velocity_overshoot: Option<f64>,
    /// The same for turn rates (0.05: up to 5 % faster); the config's
    /// `[controller] yaw_rate_overshoot` overrides it.
    pub yaw_rate_overshoot: Option<f64>,
    /// How far the vehicle's height estimate may be off (m), when the profile knows it (a
    /// barometer's on an autopilot); the config's `[safety] height_error_m` overrides it.
    pub height_error_m: Option<f64>,
}

impl Capabilities {
    /// A platform that takes velocity and position setpoints, closes no position loop of its
    /// own, takes off and lands on setpoints and flies what it is sent (the simulator's).
    pub fn setpoints_only() -> Self {
        Self {
            setpoints: AcceptedSetpoints {
                velocity: true,
                position: true,
                position_loop: None,
            },
            native_takeoff: false,
            native_land: false,
            velocity_lag_s: None,
            velocity_overshoot: None,
            yaw_rate_overshoot: None,
            height_error_m: None,
        }
    }
}

/// Everything the platform reports for one tick.
#[derive(Debug, Clone, Default)]
pub struct PlatformFeedback {
    pub status: PlatformStatus,
    pub measurements: Vec<Measurement>,
    pub scans: Vec<RangeScan>,
    /// Outcomes of requests that completed since the last tick (payload acks, refusals).
    pub request_results: Vec<RequestResult>,
    /// The vehicle came within its radius of an obstacle that exists only in a virtual world
    /// (`kestrel run --virtual-world`): what it touched, once per episode. The vehicle itself is
    /// unharmed; the core fails what runs (`virtual_collision`) and holds it where it is.
    pub virtual_collision: Option<String>,
    /// What happened to the vehicle since the last tick that no request asked for.
    pub events: Vec<PlatformEvent>,
}

/// Something the platform saw happen that was not the answer to a request.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", tag = "event")]
pub enum PlatformEvent {
    /// The autopilot left the mode Kestrel flies it in without Kestrel asking: a pilot's mode
    /// switch, a ground station's mode change or land command, a disarm in flight, or the
    /// autopilot's own failsafe while the link was up. `mode` is the mode it is in now (as the
    /// autopilot names it); `disarmed` when it was disarmed in the air. Kestrel stops commanding
    /// the vehicle until an operator gives it a new order.
    PilotTakeover { mode: String, disarmed: bool },
}

impl PlatformEvent {
    /// The event in words, as failures, alerts and the ground station show it:
    /// `pilot took over (mode AUTO.LOITER)`.
    pub fn reason(&self) -> String {
        match self {
            PlatformEvent::PilotTakeover {
                mode,
                disarmed: false,
            } => format!("pilot took over (mode {mode})"),
            PlatformEvent::PilotTakeover {
                mode,
                disarmed: true,
            } => format!("pilot took over (disarmed in the air, mode {mode})"),
        }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RequestResult {
    pub request: PlatformRequest,
    /// `Err` carries the autopilot's own reason.
    pub outcome: Result<(), RequestRefused>,
}

/// Why the platform did not carry out a request, in words for an operator: the autopilot's own
/// text where it gave one, else what went wrong on the way (no answer, the link lost, a newer
/// request). Serialized as the words alone.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, thiserror::Error)]
#[serde(transparent)]
#[error("{0}")]
pub struct RequestRefused(pub String);

impl From<String> for RequestRefused {
    fn from(reason: String) -> Self {
        Self(reason)
    }
}

impl From<&str> for RequestRefused {
    fn from(reason: &str) -> Self {
        Self(reason.to_string())
    }
}
