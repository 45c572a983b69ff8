//! The vehicle as the autopilot reports it: decoded MAVLink in, Kestrel's view out.
//!
//! In: every `MavMessage` from the autopilot with its header and arrival time. Out: a
//! [`PlatformStatus`] (link, mode, armed, landed state, readiness, battery, last error), the
//! latest [`Measurement::AutopilotOdometry`] in ENU/FLU, range scans, and the
//! [`ModelEvent`]s the session reacts to (first contact, reboot, texts). Pure: no I/O, no clock;
//! replay tests feed it recorded messages.

mod ingest;

use super::boot_clock::BootClock;
use super::events::AutopilotText;
use super::profile::Profile;
use super::velocity_check::VelocityCheck;
use crate::types::scan::RangeScan;
use crate::types::Measurement;
use crate::types::{Battery, FlightStatus, LinkHealth, PlatformStatus, Pose, Validity, Vec3};
use mavlink::dialects::ardupilotmega::MavLandedState;
use mavlink::MavHeader;
use nalgebra::UnitQuaternion;
use std::collections::VecDeque;
use std::time::Duration;

/// A position or attitude older than this is no longer valid.
const ESTIMATE_TIMEOUT: Duration = Duration::from_millis(500);

/// Why the autopilot cannot arm and fly offboard yet; `gps` is the GPS's fix and satellites in
/// words, when it reported them.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum NotReady {
    /// The autopilot is not the profile's (the words say which each is).
    #[error("{0}")]
    WrongAutopilot(String),
    #[error("no heartbeat from the autopilot")]
    NoHeartbeat,
    #[error("no position estimate yet (EKF_STATUS_REPORT flags {flags:#x}{gps})")]
    NoEstimate { flags: u16, gps: String },
    #[error("pre-arm checks failing")]
    PreArmFailing,
    #[error("no local position estimate from the autopilot{gps}")]
    NoLocalPosition { gps: String },
}

/// What the session must react to after a message.
#[derive(Debug, Clone, PartialEq)]
pub enum ModelEvent {
    /// The first HEARTBEAT of the autopilot (or the first after a link loss).
    Contact {
        system_id: u8,
        component_id: u8,
    },
    /// The autopilot restarted (its boot clock went back).
    Rebooted,
    Text(AutopilotText),
}

#[derive(Debug, Clone, Copy)]
struct LocalPosition {
    position_enu_m: Vec3,
    velocity_enu_mps: Vec3,
    at: Duration,
    /// Set when the autopilot restarted: the last estimate is kept but never valid again.
    stale: bool,
}

#[derive(Debug, Clone, Copy)]
struct Attitude {
    orientation: UnitQuaternion<f64>,
    rates_flu_radps: Vec3,
    at: Duration,
}

pub struct VehicleModel {
    profile: Profile,
    /// Only this system id is followed when set (config); otherwise the first autopilot heard.
    wanted_system: Option<u8>,
    autopilot: Option<(u8, u8)>,
    wrong_autopilot: Option<String>,
    /// Last message of any kind from the autopilot: on a lossy link telemetry proves life too.
    last_seen: Option<Duration>,
    /// Set when the link times out; only a HEARTBEAT clears it.
    link_lost: bool,
    custom_mode: Option<u32>,
    armed: bool,
    landed_state: Option<MavLandedState>,
    battery: Option<Battery>,
    ekf_flags: Option<u16>,
    /// GPS_RAW_INT: (fix type, satellites), to explain a missing position.
    gps: Option<(u8, u8)>,
    prearm_ok: Option<bool>,
    position: Option<LocalPosition>,
    attitude: Option<Attitude>,
    home_enu_m: Option<Vec3>,
    home_amsl_m: Option<f64>,
    origin_seen: bool,
    boot_clock: BootClock,
    boot_counter: u32,
    reset_counter: u32,
    texts: VecDeque<AutopilotText>,
    last_error: Option<String>,
    scans: VecDeque<RangeScan>,
    dropped_scans: u64,
    /// The velocity estimate against the position (the profile's `velocity_check`).
    velocity_check: Option<VelocityCheck>,
}

impl VehicleModel {
    pub fn new(profile: Profile, wanted_system: Option<u8>) -> Self {
        Self {
            wanted_system,
            autopilot: None,
            wrong_autopilot: None,
            last_seen: None,
            link_lost: false,
            custom_mode: None,
            armed: false,
            landed_state: None,
            battery: None,
            ekf_flags: None,
            gps: None,
            prearm_ok: None,
            position: None,
            attitude: None,
            home_enu_m: None,
            home_amsl_m: None,
            origin_seen: false,
            boot_clock: BootClock::default(),
            boot_counter: 0,
            reset_counter: 0,
            texts: VecDeque::new(),
            last_error: None,
            scans: VecDeque::new(),
            dropped_scans: 0,
            velocity_check: profile
                .velocity_check
                .map(|t| VelocityCheck::new(t.as_secs_f64())),
            profile,
        }
    }

    pub fn profile(&self) -> &Profile {
        &self.profile
    }

    /// (system id, component id) of the autopilot followed, once heard.
    pub fn autopilot(&self) -> Option<(u8, u8)> {
        self.autopilot
    }

    pub fn custom_mode(&self) -> Option<u32> {
        self.custom_mode
    }

    pub fn armed(&self) -> bool {
        self.armed
    }

    /// True when the autopilot is in the profile's offboard mode.
    pub fn offboard(&self) -> bool {
        self.custom_mode == Some(self.profile.roles.offboard.custom_mode)
    }

    pub fn landed_state(&self) -> Option<MavLandedState> {
        self.landed_state
    }

    pub fn home_enu_m(&self) -> Option<Vec3> {
        self.home_enu_m
    }

    /// Altitude of home above mean sea level (HOME_POSITION), for PX4's NAV_TAKEOFF.
    pub fn home_amsl_m(&self) -> Option<f64> {
        self.home_amsl_m
    }

    /// The autopilot's last refusal or fault in its own words (or Kestrel's, e.g. a reboot).
    pub fn last_problem(&self) -> Option<String> {
        self.last_error.clone()
    }

    /// GPS_GLOBAL_ORIGIN was reported: the autopilot has an EKF origin.
    pub fn origin_seen(&self) -> bool {
        self.origin_seen
    }

    pub fn texts(&self) -> impl Iterator<Item = &AutopilotText> {
        self.texts.iter()
    }

    pub fn dropped_scans(&self) -> u64 {
        self.dropped_scans
    }

    /// Records a refusal or fault in the autopilot's (or Kestrel's) words.
    pub fn set_error(&mut self, error: String) {
        self.last_error = Some(error);
    }

    pub fn link(&self, now: Duration) -> LinkHealth {
        match self.last_seen {
            None => LinkHealth::Connecting,
            Some(_) if self.link_lost => LinkHealth::Lost,
            Some(t) if now.saturating_sub(t) > self.profile.heartbeat_timeout => LinkHealth::Lost,
            Some(_) => LinkHealth::Ok,
        }
    }

    /// Called by the session each tick; returns true once when the link has just been lost.
    pub fn check_link(&mut self, now: Duration) -> bool {
        let newly = !self.link_lost && self.link(now) == LinkHealth::Lost;
        self.link_lost |= newly;
        newly
    }

    fn fresh(at: Duration, now: Duration) -> bool {
        now.saturating_sub(at) <= ESTIMATE_TIMEOUT
    }

    /// `Ok` when the autopilot can arm and fly offboard, else why not.
    pub fn readiness(&self, now: Duration) -> Result<(), NotReady> {
        if let Some(e) = &self.wrong_autopilot {
            return Err(NotReady::WrongAutopilot(e.clone()));
        }
        if self.link(now) != LinkHealth::Ok {
            return Err(NotReady::NoHeartbeat);
        }
        let r = self.profile.readiness;
        if r.ekf_flags_required != 0 || r.ekf_flags_forbidden != 0 {
            let flags = self.ekf_flags.unwrap_or(0);
            if flags & r.ekf_flags_required != r.ekf_flags_required
                || flags & r.ekf_flags_forbidden != 0
            {
                return Err(NotReady::NoEstimate {
                    flags,
                    gps: self.gps_words(),
                });
            }
        }
        if r.prearm_check_bit && self.prearm_ok == Some(false) && !self.armed {
            return Err(NotReady::PreArmFailing);
        }
        match self.position {
            Some(p) if !p.stale && Self::fresh(p.at, now) => Ok(()),
            _ => Err(NotReady::NoLocalPosition {
                gps: self.gps_words(),
            }),
        }
    }

    fn gps_words(&self) -> String {
        self.gps
            .map(|(fix, sats)| format!("; GPS fix type {fix}, {sats} satellites"))
            .unwrap_or_default()
    }

    fn flight(&self) -> FlightStatus {
        if !self.armed {
            return FlightStatus::Disarmed;
        }
        match self.landed_state {
            Some(MavLandedState::MAV_LANDED_STATE_IN_AIR) => FlightStatus::Flying,
            Some(MavLandedState::MAV_LANDED_STATE_TAKEOFF) => FlightStatus::TakingOff,
            Some(MavLandedState::MAV_LANDED_STATE_LANDING) => FlightStatus::Landing,
            _ => FlightStatus::Landed,
        }
    }

    pub fn status(&self, now: Duration) -> PlatformStatus {
        PlatformStatus {
            link: self.link(now),
            armed: self.armed,
            offboard: self.offboard(),
            flight: self.flight(),
            mode: self
                .custom_mode
                .map(|m| self.profile.mode_name(m))
                .unwrap_or_default(),
            ready_to_fly: self.readiness(now).is_ok(),
            battery: self.battery,
            last_error: self.last_error.clone(),
            boot_counter: self.boot_counter,
            ..PlatformStatus::default()
        }
    }

    /// The autopilot's latest estimate, or `None` before the first local position.
    pub fn odometry(&self, now: Duration) -> Option<Measurement> {
        let p = self.position?;
        let att = self.attitude;
        let orientation = att.map_or_else(UnitQuaternion::identity, |a| a.orientation);
        let position_ok = !p.stale && Self::fresh(p.at, now);
        let attitude_ok = att.is_some_and(|a| Self::fresh(a.at, now));
        Some(Measurement::AutopilotOdometry {
            pose: Pose {
                position_m: p.position_enu_m,
                orientation,
            },
            velocity_enu_mps: p.velocity_enu_mps,
            angular_velocity_flu_radps: att.map_or_else(Vec3::zeros, |a| a.rates_flu_radps),
            valid: Validity {
                position: position_ok,
                velocity: position_ok,
                attitude: attitude_ok,
            },
            reset_counter: self.reset_counter,
        })
    }

    pub fn take_scans(&mut self) -> Vec<RangeScan> {
        self.scans.drain(..).collect()
    }

    /// Forgets the vehicle's state after a reboot or a link loss that outlived it.
    fn forget_estimate(&mut self) {
        // Keep reporting the last estimate as invalid (rather than nothing), so that the
        // estimator drops its validity until the autopilot reports a new one.
        if let Some(p) = self.position.as_mut() {
            p.stale = true;
        }
        self.attitude = None;
        self.ekf_flags = None;
        self.landed_state = None;
        self.origin_seen = false;
        self.reset_counter += 1;
        if let Some(check) = self.velocity_check.as_mut() {
            check.reset();
        }
    }

    /// What to add to a velocity sent so the vehicle flies it: the bias of the autopilot's
    /// velocity estimate (ENU, m/s; zero without the check).
    pub fn velocity_bias_enu_mps(&self) -> Vec3 {
        self.velocity_check
            .as_ref()
            .map_or_else(Vec3::zeros, VelocityCheck::bias_enu_mps)
    }

    /// The vehicle is in the air by its landed state (taking off, flying or landing).
    pub fn airborne(&self) -> bool {
        self.flight().is_airborne()
    }

    /// The message came from the autopilot followed.
    pub fn is_from_autopilot(&self, header: &MavHeader) -> bool {
        self.autopilot.is_some_and(|(sys, comp)| {
            header.system_id == u32::from(sys) && header.component_id == comp
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::platform::mavlink::testutil::{self, hb, px4_profile};
    use mavlink::dialects::ardupilotmega::*;

    fn ap() -> MavHeader {
        testutil::autopilot_header()
    }

    #[test]
    fn heartbeat_gives_mode_armed_and_link() {
        let mut m = VehicleModel::new(px4_profile(), None);
        assert_eq!(m.link(Duration::ZERO), LinkHealth::Connecting);
        let ev = m.ingest(Duration::ZERO, &ap(), &hb(0x0006_0000, true));
        assert!(matches!(ev, Some(ModelEvent::Contact { system_id: 1, .. })));
        let s = m.status(Duration::from_millis(100));
        assert_eq!(s.mode, "OFFBOARD");
        assert!(s.armed && s.offboard);
        assert_eq!(s.link, LinkHealth::Ok);
        assert_eq!(m.link(Duration::from_secs(2)), LinkHealth::Lost);
        assert!(m.check_link(Duration::from_secs(2)));
        assert!(!m.check_link(Duration::from_secs(3)));
    }

    #[test]
    fn wrong_autopilot_is_reported() {
        let mut m = VehicleModel::new(px4_profile(), None);
        let mut h = hb(4, false);
        if let MavMessage::HEARTBEAT(d) = &mut h {
            d.autopilot = MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA;
        }
        m.ingest(Duration::ZERO, &ap(), &h);
        let reason = m.readiness(Duration::ZERO).unwrap_err().to_string();
        assert!(reason.contains("expects MAV_AUTOPILOT 12"), "{reason}");
    }

    /// PX4's profile checks the velocity estimate against the position: a vehicle standing
    /// still whose estimate says 0.6 m/s north is read as standing still, and a velocity sent
    /// to it gets the bias added (PX4 holds its estimate at what it hears).
    #[test]
    fn a_velocity_estimate_the_position_contradicts_is_corrected_both_ways() {
        let mut m = VehicleModel::new(px4_profile(), None);
        m.ingest(Duration::ZERO, &ap(), &hb(0, false));
        for i in 0..50 {
            let lp = MavMessage::LOCAL_POSITION_NED(LOCAL_POSITION_NED_DATA {
                time_boot_ms: 1000 + 20 * i,
                x: 2.0,
                y: 1.0,
                z: -3.0,
                vx: 0.6,
                ..LOCAL_POSITION_NED_DATA::DEFAULT
            });
            m.ingest(Duration::from_millis(u64::from(20 * i)), &ap(), &lp);
        }
        let Some(Measurement::AutopilotOdometry {
            velocity_enu_mps, ..
        }) = m.odometry(Duration::from_millis(1000))
        else {
            panic!("no odometry");
        };
        assert!(velocity_enu_mps.norm() < 0.01, "{velocity_enu_mps:?}");
        let bias = m.velocity_bias_enu_mps();
        assert!((bias - Vec3::new(0.0, 0.6, 0.0)).norm() < 0.01, "{bias:?}");
        // ArduPilot's profile takes the velocity as reported.
        let m = VehicleModel::new(testutil::ardupilot_profile(), None);
        assert!(m.velocity_check.is_none());
    }

    #[test]
    fn local_position_and_attitude_become_enu_odometry() {
        let mut m = VehicleModel::new(px4_profile(), None);
        m.ingest(Duration::ZERO, &ap(), &hb(0, false));
        let lp = MavMessage::LOCAL_POSITION_NED(LOCAL_POSITION_NED_DATA {
            time_boot_ms: 1000,
            x: 10.0,
            y: 5.0,
            z: -3.0,
            vx: 1.0,
            vy: 0.0,
            vz: 0.5,
        });
        let att = MavMessage::ATTITUDE(ATTITUDE_DATA {
            time_boot_ms: 1000,
            yaw: 0.0,
            yawspeed: 0.2,
            ..ATTITUDE_DATA::DEFAULT
        });
        m.ingest(Duration::ZERO, &ap(), &lp);
        m.ingest(Duration::ZERO, &ap(), &att);
        let Some(Measurement::AutopilotOdometry {
            pose,
            velocity_enu_mps,
            angular_velocity_flu_radps,
            valid,
            ..
        }) = m.odometry(Duration::from_millis(10))
        else {
            panic!("no odometry");
        };
        assert_eq!(pose.position_m, Vec3::new(5.0, 10.0, 3.0));
        assert_eq!(velocity_enu_mps, Vec3::new(0.0, 1.0, -0.5));
        assert!((pose.yaw_rad() - std::f64::consts::FRAC_PI_2).abs() < 1e-6);
        assert!((angular_velocity_flu_radps.z + 0.2).abs() < 1e-6);
        assert!(valid.all());
        assert!(m.readiness(Duration::from_millis(10)).is_ok());
        let stale = m.odometry(Duration::from_secs(1));
        assert!(
            matches!(stale, Some(Measurement::AutopilotOdometry { valid, .. }) if !valid.position)
        );
    }

    #[test]
    fn boot_clock_going_back_is_a_reboot() {
        let mut m = VehicleModel::new(px4_profile(), None);
        m.ingest(Duration::ZERO, &ap(), &hb(0, false));
        let at = |ms| {
            MavMessage::ATTITUDE(ATTITUDE_DATA {
                time_boot_ms: ms,
                ..ATTITUDE_DATA::DEFAULT
            })
        };
        assert_eq!(m.ingest(Duration::ZERO, &ap(), &at(60_000)), None);
        let lp = MavMessage::LOCAL_POSITION_NED(LOCAL_POSITION_NED_DATA {
            time_boot_ms: 60_000,
            ..LOCAL_POSITION_NED_DATA::DEFAULT
        });
        m.ingest(Duration::ZERO, &ap(), &lp);
        assert!(m.readiness(Duration::ZERO).is_ok());
        assert_eq!(m.ingest(Duration::ZERO, &ap(), &at(59_990)), None);
        // The restarted clock is believed once it has counted on for a second (boot_clock.rs).
        let events: Vec<_> = (0..=20u32)
            .filter_map(|i| {
                let now = Duration::from_millis(u64::from(i) * 50);
                m.ingest(now, &ap(), &at(300 + i * 50))
            })
            .collect();
        assert_eq!(events, vec![ModelEvent::Rebooted]);
        let s = m.status(Duration::from_secs(1));
        assert_eq!(s.boot_counter, 1);
        assert!(!s.ready_to_fly);
        let odometry = m.odometry(Duration::from_secs(1));
        assert!(
            matches!(odometry, Some(Measurement::AutopilotOdometry { valid, .. }) if !valid.position),
            "the estimate from before the reboot is kept, invalid: {odometry:?}"
        );
        assert_eq!(s.last_error.as_deref(), Some("the autopilot rebooted"));
    }

    #[test]
    fn spoofed_boot_times_are_not_reboots() {
        let mut m = VehicleModel::new(px4_profile(), None);
        m.ingest(Duration::ZERO, &ap(), &hb(0, false));
        let time = |ms| {
            MavMessage::SYSTEM_TIME(SYSTEM_TIME_DATA {
                time_boot_ms: ms,
                ..SYSTEM_TIME_DATA::DEFAULT
            })
        };
        let mut events = Vec::new();
        for i in 0..3_000u32 {
            let now = Duration::from_millis(u64::from(i) * 20);
            let live = 120_000 + i * 20;
            for ms in [live, i % 50, live / 3, u32::MAX] {
                events.extend(m.ingest(now, &ap(), &time(ms)));
            }
        }
        assert!(events.is_empty(), "{} false reboot reports", events.len());
        assert_eq!(m.status(Duration::from_secs(60)).boot_counter, 0);
    }

    #[test]
    fn another_autopilot_is_followed_only_after_the_first_falls_silent() {
        let rogue = MavHeader {
            system_id: 7,
            ..ap()
        };
        let mut m = VehicleModel::new(px4_profile(), None);
        assert!(m.ingest(Duration::ZERO, &rogue, &hb(0, false)).is_some());
        assert!(m
            .ingest(Duration::from_millis(500), &ap(), &hb(0, false))
            .is_none());
        assert_eq!(m.autopilot(), Some((7, ap().component_id)));
        // The first one falls silent: the next autopilot heard is followed.
        let later = Duration::from_secs(10);
        let ev = m.ingest(later, &ap(), &hb(0, false));
        assert!(
            matches!(ev, Some(ModelEvent::Contact { system_id: 1, .. })),
            "{ev:?}"
        );
        assert_eq!(m.link(later), LinkHealth::Ok);
        // Never while the one followed was last heard armed.
        let mut armed = VehicleModel::new(px4_profile(), None);
        assert!(armed.ingest(Duration::ZERO, &ap(), &hb(0, true)).is_some());
        assert!(armed.ingest(later, &rogue, &hb(0, false)).is_none());
        assert_eq!(armed.autopilot(), Some((1, ap().component_id)));
        assert_eq!(armed.link(later), LinkHealth::Lost);
        // With a configured system id the rogue never captures it.
        let mut m = VehicleModel::new(px4_profile(), Some(1));
        assert!(m.ingest(Duration::ZERO, &rogue, &hb(0, false)).is_none());
        assert!(m.ingest(Duration::ZERO, &ap(), &hb(0, false)).is_some());
        assert_eq!(m.autopilot(), Some((1, ap().component_id)));
    }

    #[test]
    fn ekf_flags_gate_readiness_on_ardupilot() {
        let mut m = VehicleModel::new(testutil::ardupilot_profile(), None);
        let mut h = hb(4, false);
        if let MavMessage::HEARTBEAT(d) = &mut h {
            d.autopilot = MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA;
        }
        m.ingest(Duration::ZERO, &ap(), &h);
        let lp = MavMessage::LOCAL_POSITION_NED(LOCAL_POSITION_NED_DATA::DEFAULT);
        m.ingest(Duration::ZERO, &ap(), &lp);
        let ekf = |bits| {
            MavMessage::EKF_STATUS_REPORT(EKF_STATUS_REPORT_DATA {
                flags: EkfStatusFlags::from_bits_truncate(bits),
                ..EKF_STATUS_REPORT_DATA::DEFAULT
            })
        };
        m.ingest(Duration::ZERO, &ap(), &ekf(0xA7));
        assert!(m
            .readiness(Duration::ZERO)
            .unwrap_err()
            .to_string()
            .contains("0xa7"));
        m.ingest(Duration::ZERO, &ap(), &ekf(0x33F));
        assert!(m.readiness(Duration::ZERO).is_ok());
    }

    #[test]
    fn problem_texts_become_last_error_and_landed_state_flight() {
        let mut m = VehicleModel::new(px4_profile(), None);
        m.ingest(Duration::ZERO, &ap(), &hb(0, true));
        let ev = MavMessage::EVENT(EVENT_DATA {
            id: 16_910_493,
            log_levels: 0x62,
            ..EVENT_DATA::DEFAULT
        });
        assert!(matches!(
            m.ingest(Duration::ZERO, &ap(), &ev),
            Some(ModelEvent::Text(_))
        ));
        let ess = MavMessage::EXTENDED_SYS_STATE(EXTENDED_SYS_STATE_DATA {
            landed_state: MavLandedState::MAV_LANDED_STATE_LANDING,
            ..EXTENDED_SYS_STATE_DATA::DEFAULT
        });
        m.ingest(Duration::ZERO, &ap(), &ess);
        let s = m.status(Duration::ZERO);
        assert_eq!(s.flight, FlightStatus::Landing);
        assert_eq!(
            s.last_error.as_deref(),
            Some("Arming denied: Resolve system health failures first")
        );
    }

    #[test]
    fn messages_from_other_systems_are_ignored() {
        let mut m = VehicleModel::new(px4_profile(), None);
        m.ingest(Duration::ZERO, &ap(), &hb(0, false));
        let gcs = MavHeader {
            system_id: 255,
            component_id: 190,
            sequence: 0,
        };
        let lp = MavMessage::LOCAL_POSITION_NED(LOCAL_POSITION_NED_DATA::DEFAULT);
        m.ingest(Duration::ZERO, &gcs, &lp);
        assert!(m.odometry(Duration::ZERO).is_none());
    }
}
