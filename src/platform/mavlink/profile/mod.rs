//! Autopilot profiles: what differs between PX4 and ArduPilot, as data (`platforms/*.toml`).
//!
//! In: the TOML text of a profile. Out: a validated [`Profile`] (mode numbers by name, the role
//! each mode plays, how to take off and land, message rates, timeouts). Unknown keys are
//! refused; every duration is in seconds and every rate in hertz, as the key names say.

use crate::types::PositionLoop;
use mavlink::dialects::ardupilotmega::MavMessage;
use mavlink::Message;
use serde::Deserialize;
use std::collections::BTreeMap;
use std::path::Path;
use std::time::Duration;

mod validate;
use validate::validate;

/// Which autopilot family a profile is written for; checked against HEARTBEAT.autopilot.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum AutopilotKind {
    /// MAV_AUTOPILOT_PX4 (12): `custom_mode = main << 16 | sub << 24`.
    Px4,
    /// MAV_AUTOPILOT_ARDUPILOTMEGA (3): `custom_mode` is the mode number.
    Ardupilot,
}

impl AutopilotKind {
    /// The HEARTBEAT.autopilot value of this family.
    pub fn mav_autopilot(self) -> u8 {
        match self {
            Self::Px4 => 12,
            Self::Ardupilot => 3,
        }
    }
}

/// How the vehicle leaves the ground.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TakeoffMethod {
    /// Climb on Kestrel's own setpoints in the offboard mode (PX4 OFFBOARD).
    OffboardSetpoints,
    /// MAV_CMD_NAV_TAKEOFF (ArduPilot GUIDED; PX4 AUTO.TAKEOFF).
    NavTakeoff,
}

/// What NAV_TAKEOFF's param 7 means for this autopilot.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TakeoffAltitude {
    /// Height above the takeoff point (ArduPilot).
    Relative,
    /// Altitude above mean sea level (PX4).
    Amsl,
}

/// How the autopilot is asked to land.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LandMethod {
    /// Switch to the mode with role `land`.
    Mode,
    /// MAV_CMD_NAV_LAND.
    NavLand,
    /// Kestrel flies the descent on its setpoints, holding its position loop down to touchdown,
    /// and disarms on the autopilot's landed state (the behavior `land` without `native_land`).
    /// A request for the autopilot's own landing still switches to the `land` mode.
    Setpoints,
}

/// What to do when SET_MESSAGE_INTERVAL is refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum IntervalFallback {
    None,
    /// REQUEST_DATA_STREAM (all streams) at the highest requested rate.
    RequestDataStream,
}

/// How a gimbal is pointed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum GimbalProtocol {
    /// Gimbal protocol v2 (MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW), MAV_CMD_DO_MOUNT_CONTROL if refused.
    ManagerV2,
    /// MAV_CMD_DO_MOUNT_CONTROL only (older ArduPilot mounts).
    MountControl,
}

/// How Kestrel drives the vehicle (the `[drive]` table; absent: position targets, gains 1).
#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawDrive {
    setpoints: DriveSetpoints,
    #[serde(default = "default_lag")]
    velocity_lag_s: f64,
    #[serde(default = "unit_gain")]
    position_gain_xy_per_s: f64,
    #[serde(default = "unit_gain")]
    position_gain_z_per_s: f64,
    /// Low-pass time constant of the velocity check (s; absent: no check). See
    /// [`super::velocity_check`].
    #[serde(default)]
    velocity_check_s: Option<f64>,
    /// Fastest change of the velocity sent (m/s^2; absent: sent as commanded). See
    /// [`super::slew`].
    #[serde(default)]
    command_slew_mps2: Option<f64>,
    /// How much faster than a velocity it is sent the vehicle may fly (a fraction; absent: 0).
    #[serde(default)]
    velocity_overshoot: Option<f64>,
    /// How much faster than a turn rate it is sent the vehicle may turn (a fraction; absent: 0).
    #[serde(default)]
    yaw_rate_overshoot: Option<f64>,
}

fn unit_gain() -> f64 {
    1.0
}

fn default_lag() -> f64 {
    0.25
}

impl Default for RawDrive {
    fn default() -> Self {
        Self {
            setpoints: DriveSetpoints::PositionTarget,
            velocity_lag_s: default_lag(),
            position_gain_xy_per_s: 1.0,
            position_gain_z_per_s: 1.0,
            velocity_check_s: None,
            command_slew_mps2: None,
            velocity_overshoot: None,
            yaw_rate_overshoot: None,
        }
    }
}

/// What SET_POSITION_TARGET_LOCAL_NED carries while Kestrel flies the vehicle.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DriveSetpoints {
    /// A moving reference point with its velocity as feed-forward; the autopilot's own tuned
    /// position loop holds the vehicle on it (as MAVSDK and MAVROS offboard trajectories do).
    PositionTarget,
    /// Velocities only: Kestrel closes the position loop over the link.
    Velocity,
}

/// One mode as the profile file writes it: `{ main = 4, sub = 6 }` (PX4) or `{ number = 9 }`.
#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawMode {
    main: Option<u8>,
    sub: Option<u8>,
    number: Option<u32>,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawRoles {
    offboard: String,
    land: String,
    hold: String,
    rtl: Option<String>,
    takeoff: Option<String>,
}

#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawReadiness {
    #[serde(default)]
    ekf_flags_required: u16,
    #[serde(default)]
    ekf_flags_forbidden: u16,
    #[serde(default)]
    prearm_check_bit: bool,
}

/// The `platform` key every file in `platforms/` starts with; this module reads `mavlink` ones.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
enum PlatformKey {
    Mavlink,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawProfile {
    platform: PlatformKey,
    name: String,
    autopilot: AutopilotKind,
    takeoff: TakeoffMethod,
    takeoff_altitude: TakeoffAltitude,
    land: LandMethod,
    arm_in_offboard_mode: bool,
    setpoint_rate_hz: f64,
    setpoint_max_age_s: f64,
    offboard_prestream_s: f64,
    offboard_loss_timeout_s: f64,
    heartbeat_timeout_s: f64,
    command_timeout_s: f64,
    command_retries: u8,
    mode_confirm_timeout_s: f64,
    ready_timeout_s: f64,
    message_interval_fallback: IntervalFallback,
    gimbal: GimbalProtocol,
    camera_component: u8,
    readiness: RawReadiness,
    modes: BTreeMap<String, RawMode>,
    roles: RawRoles,
    message_intervals_hz: BTreeMap<String, f64>,
    #[serde(default)]
    drive: RawDrive,
    /// How far the autopilot's height estimate may be off (m); absent: taken as exact.
    #[serde(default)]
    height_error_m: Option<f64>,
}

/// A named autopilot mode with its HEARTBEAT `custom_mode` value.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Mode {
    pub name: String,
    pub custom_mode: u32,
}

/// The modes Kestrel switches to.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Roles {
    /// Follows Kestrel's setpoints (PX4 OFFBOARD, ArduPilot GUIDED).
    pub offboard: Mode,
    pub land: Mode,
    /// Holds position on its own (PX4 AUTO.LOITER, ArduPilot LOITER/BRAKE).
    pub hold: Mode,
    pub rtl: Option<Mode>,
    /// Mode entered by NAV_TAKEOFF (PX4 AUTO.TAKEOFF); `None` when takeoff stays in offboard.
    pub takeoff: Option<Mode>,
}

/// When the autopilot is ready to arm and fly offboard (besides a local position estimate).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Readiness {
    /// EKF_STATUS_REPORT flags that must all be set (ArduPilot: 0x10 absolute position).
    pub ekf_flags_required: u16,
    /// EKF_STATUS_REPORT flags that must all be clear (ArduPilot: 0x80 constant position mode).
    pub ekf_flags_forbidden: u16,
    /// Require SYS_STATUS's pre-arm check bit to be healthy when the autopilot reports it.
    pub prearm_check_bit: bool,
}

/// A validated autopilot profile.
#[derive(Debug, Clone, PartialEq)]
pub struct Profile {
    pub name: String,
    pub autopilot: AutopilotKind,
    pub takeoff: TakeoffMethod,
    pub takeoff_altitude: TakeoffAltitude,
    pub land: LandMethod,
    /// Enter the offboard mode before arming (ArduPilot arms in GUIDED, then NAV_TAKEOFF).
    pub arm_in_offboard_mode: bool,
    /// Setpoint stream period while a fresh setpoint is available.
    pub setpoint_period: Duration,
    /// A setpoint older than this is never sent again: the stream stops and the autopilot's own
    /// offboard-loss failsafe acts when Kestrel's control loop stalls.
    pub setpoint_max_age: Duration,
    /// Stream setpoints this long before asking for the offboard mode (PX4 needs about 1 s).
    pub offboard_prestream: Duration,
    /// The autopilot leaves offboard this long after the last setpoint (PX4 COM_OF_LOSS_T,
    /// ArduPilot GUID_TIMEOUT for velocity targets).
    pub offboard_loss_timeout: Duration,
    /// The link is lost after this long without HEARTBEAT or telemetry from the autopilot; only
    /// a HEARTBEAT brings it back.
    pub heartbeat_timeout: Duration,
    /// Wait this long for a COMMAND_ACK before re-sending with `confirmation` + 1.
    pub command_timeout: Duration,
    pub command_retries: u8,
    /// A mode change is done when HEARTBEAT shows it, within this time after the ack.
    pub mode_confirm_timeout: Duration,
    /// An arm request waits this long for readiness before failing with the autopilot's reason.
    pub ready_timeout: Duration,
    pub message_interval_fallback: IntervalFallback,
    pub gimbal: GimbalProtocol,
    /// Component id that takes camera commands (100 = MAV_COMP_ID_CAMERA, 1 = the autopilot).
    pub camera_component: u8,
    pub readiness: Readiness,
    /// Every mode the autopilot may report, for naming HEARTBEAT's `custom_mode`.
    pub modes: Vec<Mode>,
    pub roles: Roles,
    /// (message id, rate) pairs requested with SET_MESSAGE_INTERVAL on connection.
    pub message_intervals: Vec<(u32, f64)>,
    /// The autopilot's position loop when it is given position targets; `None`: velocities.
    pub position_loop: Option<PositionLoop>,
    /// Time constant of the autopilot's velocity response (`[drive] velocity_lag_s`).
    pub velocity_lag: Duration,
    /// The velocity estimate is checked against the position over this time constant
    /// (`[drive] velocity_check_s`); `None`: taken as reported.
    pub velocity_check: Option<Duration>,
    /// Fastest change of the velocity setpoints sent (`[drive] command_slew_mps2`, m/s^2);
    /// `None`: sent as commanded.
    pub command_slew_mps2: Option<f64>,
    /// How much faster than a velocity it is sent the vehicle may fly, as a fraction
    /// (`[drive] velocity_overshoot`); speeds are planned and commanded within each limit
    /// divided by one plus it. `None`: the vehicle flies what it is sent.
    pub velocity_overshoot: Option<f64>,
    /// The same for turn rates (`[drive] yaw_rate_overshoot`).
    pub yaw_rate_overshoot: Option<f64>,
    /// How far the autopilot's height estimate may be off (`height_error_m`, m); missions are
    /// refused below it plus a ground clearance. `None`: taken as exact.
    pub height_error_m: Option<f64>,
}

#[derive(Debug, thiserror::Error)]
pub enum ProfileError {
    #[error("cannot read profile {path}: {source}")]
    Read {
        path: String,
        source: std::io::Error,
    },
    #[error("profile {path}: {message}")]
    Parse { path: String, message: String },
    #[error("profile {path}: {field}: {message}")]
    Invalid {
        path: String,
        field: String,
        message: String,
    },
}

impl Profile {
    pub fn load(path: &Path) -> Result<Self, ProfileError> {
        let p = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|source| ProfileError::Read {
            path: p.clone(),
            source,
        })?;
        Self::parse(&text, &p)
    }

    /// The profiles shipped in `platforms/`, by file stem (`px4`, `ardupilot-copter`).
    pub fn builtin(name: &str) -> Option<Result<Self, ProfileError>> {
        let text = match name {
            "px4" => include_str!("../../../../platforms/px4.toml"),
            "ardupilot-copter" => include_str!("../../../../platforms/ardupilot-copter.toml"),
            _ => return None,
        };
        Some(Self::parse(text, &format!("built-in {name}")))
    }

    /// Parses and validates a profile; `origin` names it in errors.
    pub fn parse(text: &str, origin: &str) -> Result<Self, ProfileError> {
        let raw: RawProfile = toml::from_str(text).map_err(|e| ProfileError::Parse {
            path: origin.to_string(),
            message: e.to_string(),
        })?;
        validate(raw).map_err(|(field, message)| ProfileError::Invalid {
            path: origin.to_string(),
            field,
            message,
        })
    }

    /// The name of a HEARTBEAT `custom_mode`, or its number when the profile does not list it.
    pub fn mode_name(&self, custom_mode: u32) -> String {
        self.modes
            .iter()
            .find(|m| m.custom_mode == custom_mode)
            .map_or_else(
                || format!("custom_mode {custom_mode:#x}"),
                |m| m.name.clone(),
            )
    }

    /// DO_SET_MODE parameters 2 and 3 for a mode (PX4: main and sub mode; ArduPilot: number).
    pub fn set_mode_params(&self, mode: &Mode) -> (f32, f32) {
        match self.autopilot {
            AutopilotKind::Px4 => (
                ((mode.custom_mode >> 16) & 0xff) as f32,
                ((mode.custom_mode >> 24) & 0xff) as f32,
            ),
            AutopilotKind::Ardupilot => (mode.custom_mode as f32, 0.0),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn load(name: &str) -> Profile {
        let path = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("platforms")
            .join(name);
        Profile::load(&path).unwrap()
    }

    #[test]
    fn shipped_profiles_load() {
        let px4 = load("px4.toml");
        assert_eq!(px4.autopilot, AutopilotKind::Px4);
        assert_eq!(px4.roles.offboard.custom_mode, 0x0006_0000);
        assert_eq!(px4.roles.land.custom_mode, 0x0604_0000);
        assert_eq!(px4.mode_name(0x0304_0000), "AUTO.LOITER");
        assert_eq!(px4.set_mode_params(&px4.roles.land), (4.0, 6.0));
        let ap = load("ardupilot-copter.toml");
        assert_eq!(ap.roles.offboard.custom_mode, 4);
        assert_eq!(ap.mode_name(9), "LAND");
        assert_eq!(ap.set_mode_params(&ap.roles.offboard), (4.0, 0.0));
        assert_eq!(ap.takeoff, TakeoffMethod::NavTakeoff);
        assert!(ap.message_intervals.iter().any(|(id, _)| *id == 32));
    }

    #[test]
    fn unknown_keys_and_wrong_mode_forms_are_refused() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("platforms/px4.toml");
        let text = std::fs::read_to_string(path).unwrap();
        let e = Profile::parse(&format!("colour = 3\n{text}"), "t").unwrap_err();
        assert!(e.to_string().contains("colour"), "{e}");
        let bad = text.replace("OFFBOARD = { main = 6 }", "OFFBOARD = { number = 6 }");
        let e = Profile::parse(&bad, "t").unwrap_err();
        assert!(e.to_string().contains("modes.OFFBOARD"), "{e}");
        let bad = text.replace("setpoint_max_age_s = 0.1", "setpoint_max_age_s = 2.0");
        let e = Profile::parse(&bad, "t").unwrap_err();
        assert!(e.to_string().contains("setpoint_max_age_s"), "{e}");
        let bad = text.replace("velocity_overshoot = 0.2", "velocity_overshoot = -0.1");
        let e = Profile::parse(&bad, "t").unwrap_err();
        assert!(e.to_string().contains("drive.velocity_overshoot"), "{e}");
        let bad = text.replace("height_error_m = 1.5", "height_error_m = -1");
        let e = Profile::parse(&bad, "t").unwrap_err();
        assert!(e.to_string().contains("height_error_m"), "{e}");
    }

    #[test]
    fn autopilots_on_a_barometer_say_their_height_may_be_off() {
        assert_eq!(load("px4.toml").height_error_m, Some(1.5));
        assert_eq!(load("ardupilot-copter.toml").height_error_m, Some(1.5));
    }

    #[test]
    fn px4_says_how_much_faster_than_sent_it_flies() {
        assert_eq!(load("px4.toml").velocity_overshoot, Some(0.2));
        assert_eq!(load("ardupilot-copter.toml").velocity_overshoot, None);
        assert_eq!(load("px4.toml").yaw_rate_overshoot, Some(0.06));
        assert_eq!(load("ardupilot-copter.toml").yaw_rate_overshoot, None);
    }
}
