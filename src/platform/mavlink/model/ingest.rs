//! One message from the autopilot into the [`VehicleModel`]: the HEARTBEAT (which autopilot is
//! followed, its mode and arming), the estimate (attitude, local position, odometry, converted
//! from NED/FRD to ENU/FLU), the boot clock, power, range sensors and texts.
//!
//! In: a decoded [`MavMessage`] with its header and arrival time. Out: the model updated, and
//! the [`ModelEvent`] the session must react to, if any.

use super::{Attitude, LocalPosition, ModelEvent, VehicleModel};
use crate::platform::mavlink::boot_clock::BootClock;
use crate::platform::mavlink::events::{self, AutopilotText};
use crate::platform::mavlink::frames;
use crate::types::scan::{self, ObstacleSectors, RangeScan, SectorFrame};
use crate::types::{Battery, LinkHealth, Vec3};
use mavlink::dialects::ardupilotmega::{
    MavAutopilot, MavFrame, MavMessage, MavModeFlag, BATTERY_STATUS_DATA, DISTANCE_SENSOR_DATA,
    LOCAL_POSITION_NED_DATA, OBSTACLE_DISTANCE_DATA, SYS_STATUS_DATA,
};
use mavlink::MavHeader;
use std::time::Duration;

/// Texts kept for explaining refusals.
const TEXT_HISTORY: usize = 64;
/// Scans kept between two polls; older ones are dropped (and counted).
const SCAN_BUFFER: usize = 256;
const SYS_STATUS_PREARM_CHECK: u32 = 0x1000_0000;

impl VehicleModel {
    /// Updates the model with one message; returns what the session must react to.
    pub fn ingest(
        &mut self,
        now: Duration,
        header: &MavHeader,
        msg: &MavMessage,
    ) -> Option<ModelEvent> {
        if let MavMessage::HEARTBEAT(hb) = msg {
            return self.heartbeat(now, header, hb);
        }
        if !self.is_from_autopilot(header) {
            return None;
        }
        self.last_seen = Some(now);
        match msg {
            MavMessage::ATTITUDE(a) => {
                self.attitude = Some(Attitude {
                    orientation: frames::attitude_from_euler_ned(
                        f64::from(a.roll),
                        f64::from(a.pitch),
                        f64::from(a.yaw),
                    ),
                    rates_flu_radps: frames::frd_to_flu(
                        f64::from(a.rollspeed),
                        f64::from(a.pitchspeed),
                        f64::from(a.yawspeed),
                    ),
                    at: now,
                });
                return self.boot_time(a.time_boot_ms, now);
            }
            MavMessage::ATTITUDE_QUATERNION(a) => {
                if let Some(q) = frames::attitude_from_mav_quaternion([a.q1, a.q2, a.q3, a.q4]) {
                    self.attitude = Some(Attitude {
                        orientation: q,
                        rates_flu_radps: frames::frd_to_flu(
                            f64::from(a.rollspeed),
                            f64::from(a.pitchspeed),
                            f64::from(a.yawspeed),
                        ),
                        at: now,
                    });
                }
                return self.boot_time(a.time_boot_ms, now);
            }
            MavMessage::LOCAL_POSITION_NED(p) => {
                self.local_position(now, p);
                return self.boot_time(p.time_boot_ms, now);
            }
            MavMessage::ODOMETRY(o) => self.odometry_message(now, o),
            MavMessage::GLOBAL_POSITION_INT(g) => return self.boot_time(g.time_boot_ms, now),
            MavMessage::SYSTEM_TIME(t) => return self.boot_time(t.time_boot_ms, now),
            MavMessage::EXTENDED_SYS_STATE(s) => self.landed_state = Some(s.landed_state),
            // PX4 sends it on every mode change; HEARTBEAT comes only once a second.
            MavMessage::CURRENT_MODE(m) => self.custom_mode = Some(m.custom_mode),
            MavMessage::SYS_STATUS(s) => self.sys_status(s),
            MavMessage::BATTERY_STATUS(b) => self.battery_status(b),
            MavMessage::EKF_STATUS_REPORT(e) => self.ekf_flags = Some(e.flags.bits()),
            MavMessage::GPS_RAW_INT(g) => self.gps = Some((g.fix_type as u8, g.satellites_visible)),
            MavMessage::HOME_POSITION(h) => {
                self.home_enu_m = Some(frames::ned_to_enu(h.x.into(), h.y.into(), h.z.into()));
                self.home_amsl_m = Some(f64::from(h.altitude) / 1000.0);
            }
            MavMessage::GPS_GLOBAL_ORIGIN(_) => self.origin_seen = true,
            MavMessage::DISTANCE_SENSOR(d) => self.distance_sensor(d),
            MavMessage::OBSTACLE_DISTANCE(o) => self.obstacle_distance(o),
            MavMessage::STATUSTEXT(s) => {
                let text = events::status_text(now, s.severity as u8, &s.text[..]);
                return self.text(text);
            }
            MavMessage::EVENT(e) => {
                return events::px4_event(now, e.id, e.log_levels).and_then(|t| self.text(t));
            }
            _ => {}
        }
        None
    }

    fn local_position(&mut self, now: Duration, p: &LOCAL_POSITION_NED_DATA) {
        let v = [p.x, p.y, p.z, p.vx, p.vy, p.vz];
        if v.iter().all(|x| x.is_finite()) {
            let position_enu_m = frames::ned_to_enu(p.x.into(), p.y.into(), p.z.into());
            let mut velocity_enu_mps = frames::ned_to_enu(p.vx.into(), p.vy.into(), p.vz.into());
            if let Some(check) = self.velocity_check.as_mut() {
                let time_s = f64::from(p.time_boot_ms) / 1000.0;
                check.observe(time_s, position_enu_m, velocity_enu_mps);
                velocity_enu_mps -= check.bias_enu_mps();
            }
            self.position = Some(LocalPosition {
                position_enu_m,
                velocity_enu_mps,
                at: now,
                stale: false,
            });
        }
    }

    /// The pre-arm check (when the autopilot reports one) and the battery.
    fn sys_status(&mut self, s: &SYS_STATUS_DATA) {
        let present = s.onboard_control_sensors_present.bits();
        if present & SYS_STATUS_PREARM_CHECK != 0 {
            let healthy = s.onboard_control_sensors_health.bits();
            self.prearm_ok = Some(healthy & SYS_STATUS_PREARM_CHECK != 0);
        }
        if s.voltage_battery != u16::MAX && s.voltage_battery > 0 {
            self.battery = Some(Battery {
                voltage_v: f64::from(s.voltage_battery) / 1000.0,
                remaining_fraction: fraction(s.battery_remaining),
            });
        }
    }

    fn battery_status(&mut self, b: &BATTERY_STATUS_DATA) {
        let mv: u32 = b
            .voltages
            .iter()
            .filter(|v| **v != u16::MAX)
            .map(|v| u32::from(*v))
            .sum();
        if mv > 0 {
            self.battery = Some(Battery {
                voltage_v: f64::from(mv) / 1000.0,
                remaining_fraction: fraction(b.battery_remaining),
            });
        }
    }

    /// One beam, cast from where the vehicle is now.
    fn distance_sensor(&mut self, d: &DISTANCE_SENSOR_DATA) {
        let beam = scan::beam_from_distance_sensor(
            d.orientation as u8,
            d.current_distance,
            d.min_distance,
            d.max_distance,
        );
        if let (Some(beam), Some(p)) = (beam, self.position) {
            self.push_scan(RangeScan {
                origin_enu_m: p.position_enu_m,
                yaw_rad: self.yaw_enu_rad(),
                range_min_m: f64::from(d.min_distance) / 100.0,
                range_max_m: f64::from(d.max_distance) / 100.0,
                beams: vec![beam],
            });
        }
    }

    /// Sectors around the vehicle, cast from where it is now.
    fn obstacle_distance(&mut self, o: &OBSTACLE_DISTANCE_DATA) {
        let Some(p) = self.position else {
            return;
        };
        let increment_deg = if o.increment_f > 0.0 {
            f64::from(o.increment_f)
        } else {
            f64::from(o.increment)
        };
        let frame = if o.frame == MavFrame::MAV_FRAME_BODY_FRD {
            SectorFrame::BodyFrd
        } else {
            SectorFrame::LocalNed
        };
        let sectors = ObstacleSectors {
            distances_cm: &o.distances,
            increment_deg,
            angle_offset_deg: f64::from(o.angle_offset),
            min_distance_cm: o.min_distance,
            max_distance_cm: o.max_distance,
            frame,
        };
        let scan = scan::from_obstacle_distance(p.position_enu_m, self.yaw_enu_rad(), &sectors);
        self.push_scan(scan);
    }

    fn yaw_enu_rad(&self) -> f64 {
        self.attitude
            .map_or(0.0, |a| a.orientation.euler_angles().2)
    }

    fn push_scan(&mut self, scan: RangeScan) {
        if self.scans.len() >= SCAN_BUFFER {
            self.scans.pop_front();
            self.dropped_scans += 1;
        }
        self.scans.push_back(scan);
    }

    fn text(&mut self, text: AutopilotText) -> Option<ModelEvent> {
        if self.texts.len() >= TEXT_HISTORY {
            self.texts.pop_front();
        }
        if text.is_problem() {
            self.last_error = Some(text.text.clone());
        }
        self.texts.push_back(text.clone());
        Some(ModelEvent::Text(text))
    }

    fn odometry_message(
        &mut self,
        now: Duration,
        o: &mavlink::dialects::ardupilotmega::ODOMETRY_DATA,
    ) {
        let q = frames::attitude_from_mav_quaternion(o.q);
        let local = matches!(
            o.frame_id,
            MavFrame::MAV_FRAME_LOCAL_NED | MavFrame::MAV_FRAME_LOCAL_FRD
        );
        let p = [o.x, o.y, o.z, o.vx, o.vy, o.vz];
        if !local || !p.iter().all(|x| x.is_finite()) {
            return;
        }
        let v_frd = Vec3::new(o.vx.into(), o.vy.into(), o.vz.into());
        let velocity_enu_mps = match (o.child_frame_id, q) {
            (MavFrame::MAV_FRAME_BODY_FRD, Some(q_enu_flu)) => {
                // Body FRD velocity → FLU → ENU with the vehicle's attitude.
                q_enu_flu * Vec3::new(v_frd.x, -v_frd.y, -v_frd.z)
            }
            (MavFrame::MAV_FRAME_BODY_FRD, None) => return,
            _ => frames::ned_to_enu(v_frd.x, v_frd.y, v_frd.z),
        };
        self.position = Some(LocalPosition {
            position_enu_m: frames::ned_to_enu(o.x.into(), o.y.into(), o.z.into()),
            velocity_enu_mps,
            at: now,
            stale: false,
        });
        if let Some(orientation) = q {
            self.attitude = Some(Attitude {
                orientation,
                rates_flu_radps: frames::frd_to_flu(
                    o.rollspeed.into(),
                    o.pitchspeed.into(),
                    o.yawspeed.into(),
                ),
                at: now,
            });
        }
    }

    fn boot_time(&mut self, time_boot_ms: u32, now: Duration) -> Option<ModelEvent> {
        if !self.boot_clock.observe(time_boot_ms, now) {
            return None;
        }
        self.boot_counter += 1;
        self.forget_estimate();
        self.last_error = Some("the autopilot rebooted".into());
        Some(ModelEvent::Rebooted)
    }

    fn heartbeat(
        &mut self,
        now: Duration,
        header: &MavHeader,
        hb: &mavlink::dialects::ardupilotmega::HEARTBEAT_DATA,
    ) -> Option<ModelEvent> {
        if hb.autopilot == MavAutopilot::MAV_AUTOPILOT_INVALID {
            return None; // a GCS, camera, gimbal or another companion
        }
        let Ok(system_id) = u8::try_from(header.system_id) else {
            return None;
        };
        if self.wanted_system.is_some_and(|s| s != system_id) {
            return None;
        }
        let silent = self.link_lost || self.link(now) == LinkHealth::Lost;
        let this = (system_id, header.component_id);
        match self.autopilot {
            // Another autopilot is followed only once the selected one has fallen silent, and
            // never when it was last heard armed: its own failsafe flies it, and commands meant
            // for it must not go to whoever answers meanwhile.
            Some(selected) if selected != this && (!silent || self.armed) => return None,
            Some(selected) if selected != this => {
                tracing::warn!(target: "mavlink", "autopilot {selected:?} silent: following {this:?}");
                self.forget_estimate();
                self.boot_clock = BootClock::default();
            }
            _ => {}
        }
        let expected = self.profile.autopilot.mav_autopilot();
        if hb.autopilot as u8 != expected {
            let e = format!(
                "profile `{}` expects MAV_AUTOPILOT {expected}, the vehicle reports {:?}",
                self.profile.name, hb.autopilot
            );
            self.last_error = Some(e.clone());
            self.wrong_autopilot = Some(e);
        } else {
            self.wrong_autopilot = None;
        }
        let first = self.autopilot.is_none() || silent;
        self.autopilot = Some(this);
        self.last_seen = Some(now);
        self.link_lost = false;
        self.custom_mode = Some(hb.custom_mode);
        self.armed = hb
            .base_mode
            .contains(MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED);
        first.then_some(ModelEvent::Contact {
            system_id,
            component_id: header.component_id,
        })
    }
}

fn fraction(percent: i8) -> Option<f64> {
    (0..=100)
        .contains(&percent)
        .then(|| f64::from(percent) / 100.0)
}
