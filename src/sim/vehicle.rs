//! One simulated vehicle behind an autopilot-like interface: arming, offboard, landed state,
//! battery, setpoint-loss failsafe. It implements [`Platform`], so the core flies it exactly as
//! it flies a MAVLink autopilot. Each poll reports the true state as ground truth, autopilot
//! odometry and an external (motion-capture) pose, so every estimator plugin can fly it. With
//! a drift ([`SimVehicle::set_drift`]) all three carry the drifting estimate instead, and the
//! autopilot's own position loop and holds use it too: the truth stays inside the simulator
//! (`state`, collisions).

use super::drift::EstimateDrift;
use super::dynamics::{self, Drive, MultirotorParams, RigidState};
use crate::platform::Platform;
use crate::types::Measurement;
use crate::types::RangeScan;
use crate::types::{
    wrap_angle_rad, Battery, FlightStatus, LinkHealth, PlatformStatus, Pose, Validity, Vec3,
};
use crate::types::{
    Capabilities, PlatformEvent, PlatformFeedback, PlatformRequest, RequestRefused, RequestResult,
};
use crate::types::{Setpoint, YawTarget};
use std::time::Duration;

/// Offboard ends (and the vehicle holds) when no setpoint came for this long, as on PX4.
const SETPOINT_TIMEOUT: Duration = Duration::from_millis(1000);
const FULL_VOLTAGE_V: f64 = 16.8;
const EMPTY_VOLTAGE_V: f64 = 13.2;
/// An armed vehicle on the ground outside offboard disarms after this long.
const AUTO_DISARM: Duration = Duration::from_secs(2);

/// Battery drain while armed (fraction per second): a full pack lasts about 25 minutes.
const DRAIN_PER_S: f64 = 1.0 / 1500.0;

pub struct SimVehicle {
    pub params: MultirotorParams,
    pub state: RigidState,
    armed: bool,
    offboard: bool,
    crashed: Option<String>,
    battery_fraction: f64,
    last_setpoint: Option<(Setpoint, Duration)>,
    /// Position held by the autopilot itself when offboard is lost.
    failsafe_hold: Option<Vec3>,
    /// Since when the vehicle sits on the ground armed outside offboard (auto-disarm).
    grounded_since: Option<Duration>,
    last_error: Option<String>,
    pending_results: Vec<RequestResult>,
    pending_events: Vec<PlatformEvent>,
    /// When the last setpoint arrived, whatever the mode (tests check who commands).
    last_setpoint_at: Option<Duration>,
    pub(super) pending_scans: Vec<RangeScan>,
    pub(super) next_scan_at: Duration,
    /// How the vehicle's own position estimate walks off the truth (none by default).
    drift: EstimateDrift,
}

impl SimVehicle {
    pub fn new(position_m: Vec3, yaw_rad: f64, params: MultirotorParams) -> Self {
        Self {
            params,
            state: RigidState {
                position_m,
                yaw_rad: wrap_angle_rad(yaw_rad),
                ..Default::default()
            },
            armed: false,
            offboard: false,
            crashed: None,
            battery_fraction: 1.0,
            last_setpoint: None,
            failsafe_hold: None,
            grounded_since: None,
            last_error: None,
            pending_results: Vec::new(),
            pending_events: Vec::new(),
            last_setpoint_at: None,
            pending_scans: Vec::new(),
            next_scan_at: Duration::ZERO,
            drift: EstimateDrift::new(0.0, 0),
        }
    }

    /// Replaces how the position estimate drifts (from no offset).
    pub fn set_drift(&mut self, drift: EstimateDrift) {
        self.drift = drift;
    }

    /// Where the vehicle believes it is (ENU m): the truth plus its estimate's drift.
    pub fn estimated_position_m(&self) -> Vec3 {
        self.state.position_m + self.drift.offset_m()
    }

    pub fn crashed(&self) -> Option<&str> {
        self.crashed.as_deref()
    }

    pub fn is_armed(&self) -> bool {
        self.armed
    }

    /// Ends the flight: motors off, the reason kept for status and logs.
    pub fn crash(&mut self, reason: String) {
        if self.crashed.is_none() {
            self.crashed = Some(reason.clone());
            self.last_error = Some(reason);
            self.armed = false;
            self.offboard = false;
        }
    }

    pub fn flight_status(&self) -> FlightStatus {
        if self.crashed.is_some() {
            FlightStatus::Crashed
        } else if !self.armed {
            FlightStatus::Disarmed
        } else if self.state.on_ground() {
            FlightStatus::Landed
        } else {
            FlightStatus::Flying
        }
    }

    /// The autopilot lands by itself where it is (its own failsafe, or a pilot's LAND switch):
    /// it leaves offboard, descends and disarms on the ground, as PX4 and ArduPilot do.
    pub fn autopilot_land(&mut self) {
        self.offboard = false;
        self.failsafe_hold = None;
    }

    /// A pilot switches the autopilot to its hold mode: it leaves offboard and holds where it is,
    /// ignoring setpoints until offboard is asked for again, and reports the takeover.
    pub fn pilot_takeover(&mut self) {
        if !self.offboard {
            return;
        }
        self.offboard = false;
        self.failsafe_hold = Some(self.estimated_position_m());
        let event = PlatformEvent::PilotTakeover {
            mode: "HOLD".into(),
            disarmed: false,
        };
        self.last_error = Some(event.reason());
        self.pending_events.push(event);
    }

    /// When the last setpoint arrived (simulated time), whatever the mode.
    pub fn last_setpoint_at(&self) -> Option<Duration> {
        self.last_setpoint_at
    }

    /// Advances the physics by `dt_s` with the wind and a noise acceleration.
    pub fn step(&mut self, now: Duration, dt_s: f64, wind_mps: &Vec3, noise_mps2: &Vec3) {
        if self.armed {
            self.battery_fraction = (self.battery_fraction - DRAIN_PER_S * dt_s).max(0.0);
        }
        let stale = self
            .last_setpoint
            .is_none_or(|(_, t)| now.saturating_sub(t) > SETPOINT_TIMEOUT);
        if self.offboard && stale && self.armed {
            // Autopilot failsafe: leave offboard and hold position.
            self.offboard = false;
            self.failsafe_hold = Some(self.estimated_position_m());
            self.last_error = Some("offboard setpoints lost: holding position".into());
        }
        // Landed outside offboard: the autopilot disarms by itself (PX4's COM_DISARM_LAND).
        if self.armed && !self.offboard && self.state.on_ground() {
            let since = *self.grounded_since.get_or_insert(now);
            if now.saturating_sub(since) >= AUTO_DISARM {
                self.armed = false;
            }
        } else {
            self.grounded_since = None;
        }
        let drive = if !self.armed {
            Drive::Off
        } else if self.offboard {
            match self.last_setpoint {
                Some((sp, _)) => self.drive_for(&sp),
                None => Drive::Velocity {
                    velocity_enu_mps: Vec3::zeros(),
                    yaw_rate_radps: 0.0,
                },
            }
        } else if let Some(hold) = self.failsafe_hold.filter(|_| !self.state.on_ground()) {
            Drive::Velocity {
                velocity_enu_mps: (hold - self.estimated_position_m()) * 1.0,
                yaw_rate_radps: 0.0,
            }
        } else {
            Drive::Velocity {
                velocity_enu_mps: Vec3::new(
                    0.0,
                    0.0,
                    if self.state.on_ground() { 0.0 } else { -0.5 },
                ),
                yaw_rate_radps: 0.0,
            }
        };
        // The autopilot's velocity loop closes on its estimate, which moves at the truth's
        // velocity plus the drift's: the truth goes the drift's way backwards.
        let drive = match drive {
            Drive::Velocity {
                velocity_enu_mps,
                yaw_rate_radps,
            } => Drive::Velocity {
                velocity_enu_mps: velocity_enu_mps - self.drift.rate_mps(),
                yaw_rate_radps,
            },
            Drive::Off => Drive::Off,
        };
        dynamics::step(
            &mut self.state,
            &self.params,
            drive,
            wind_mps,
            noise_mps2,
            dt_s,
        );
        let flying = self.flight_status() == FlightStatus::Flying;
        self.drift.step(dt_s, flying);
    }

    fn drive_for(&self, sp: &Setpoint) -> Drive {
        match *sp {
            Setpoint::Velocity {
                velocity_enu_mps,
                yaw,
            } => Drive::Velocity {
                velocity_enu_mps,
                yaw_rate_radps: self.yaw_rate_for(yaw),
            },
            Setpoint::Position {
                position_enu_m,
                velocity_ff_enu_mps,
                yaw,
            } => Drive::Velocity {
                velocity_enu_mps: velocity_ff_enu_mps
                    + (position_enu_m - self.estimated_position_m()),
                yaw_rate_radps: self.yaw_rate_for(yaw),
            },
        }
    }

    fn yaw_rate_for(&self, yaw: YawTarget) -> f64 {
        match yaw {
            YawTarget::Rate(r) => r,
            YawTarget::Angle(a) => 2.0 * wrap_angle_rad(a - self.state.yaw_rad),
        }
    }

    fn handle(&mut self, request: PlatformRequest) -> Result<(), RequestRefused> {
        match request {
            PlatformRequest::Arm => {
                if let Some(reason) = &self.crashed {
                    return Err(RequestRefused(format!("arming denied: {reason}")));
                }
                if self.battery_fraction < 0.05 {
                    return Err("arming denied: battery empty".into());
                }
                self.armed = true;
                self.failsafe_hold = None;
                Ok(())
            }
            PlatformRequest::Disarm => {
                if !self.state.on_ground() {
                    return Err("disarm refused: vehicle in air".into());
                }
                self.armed = false;
                self.offboard = false;
                Ok(())
            }
            PlatformRequest::StartOffboard => {
                if self.last_setpoint.is_none() {
                    return Err("offboard refused: no setpoint stream".into());
                }
                self.offboard = true;
                self.failsafe_hold = None;
                Ok(())
            }
            PlatformRequest::Takeoff { .. } | PlatformRequest::Land => {
                Err("the simulator flies takeoff and landing on setpoints".into())
            }
            PlatformRequest::PointGimbal { .. }
            | PlatformRequest::TakePhoto
            | PlatformRequest::LandOnSetpoints => Ok(()),
        }
    }
}

impl Platform for SimVehicle {
    fn capabilities(&self) -> Capabilities {
        Capabilities::setpoints_only()
    }

    fn poll(&mut self, now: Duration) -> PlatformFeedback {
        let s = &self.state;
        let (roll, pitch) = s.tilt_rad();
        let velocity_enu_mps = s.velocity_mps + self.drift.rate_mps();
        let pose = Pose {
            position_m: self.estimated_position_m(),
            orientation: nalgebra::UnitQuaternion::from_euler_angles(roll, pitch, s.yaw_rad),
        };
        let status = PlatformStatus {
            link: LinkHealth::Ok,
            armed: self.armed,
            offboard: self.offboard,
            flight: self.flight_status(),
            mode: if self.offboard {
                "OFFBOARD".into()
            } else {
                "HOLD".into()
            },
            ready_to_fly: self.crashed.is_none(),
            battery: Some(Battery {
                voltage_v: EMPTY_VOLTAGE_V
                    + (FULL_VOLTAGE_V - EMPTY_VOLTAGE_V) * self.battery_fraction,
                remaining_fraction: Some(self.battery_fraction),
            }),
            last_error: self.last_error.clone(),
            boot_counter: 0,
            ..PlatformStatus::default()
        };
        let angular_velocity_flu_radps = Vec3::new(0.0, 0.0, s.yaw_rate_radps);
        // The same truth as every source an estimator plugin may listen to.
        PlatformFeedback {
            status,
            measurements: vec![
                Measurement::GroundTruth {
                    pose,
                    velocity_enu_mps,
                    angular_velocity_flu_radps,
                },
                Measurement::AutopilotOdometry {
                    pose,
                    velocity_enu_mps,
                    angular_velocity_flu_radps,
                    valid: Validity::ALL,
                    reset_counter: 0,
                },
                Measurement::ExternalPose { pose, stamp: now },
            ],
            scans: std::mem::take(&mut self.pending_scans),
            request_results: std::mem::take(&mut self.pending_results),
            virtual_collision: None,
            events: std::mem::take(&mut self.pending_events),
        }
    }

    fn command(&mut self, now: Duration, setpoint: Option<Setpoint>, requests: &[PlatformRequest]) {
        if let Some(sp) = setpoint {
            self.last_setpoint = Some((sp, now));
            self.last_setpoint_at = Some(now);
        }
        for &request in requests {
            let outcome = self.handle(request);
            if let Err(e) = &outcome {
                self.last_error = Some(e.to_string());
            }
            self.pending_results
                .push(RequestResult { request, outcome });
        }
    }
}
