//! Setpoints out: ENU [`Setpoint`]s as SET_POSITION_TARGET_LOCAL_NED, streamed only while fresh.
//!
//! In: the setpoint of each control tick (or `None`) and the time. Out: the message to send
//! now, if any. The stream runs at the profile's period while the latest setpoint is younger
//! than its maximum age; when Kestrel's control loop stalls the stream stops, so the
//! autopilot's own offboard-loss failsafe acts instead of flying a stale command.

use super::frames;
use crate::types::Vec3;
use crate::types::{Setpoint, YawTarget};
use mavlink::dialects::ardupilotmega::{
    MavFrame, PositionTargetTypemask, SET_POSITION_TARGET_LOCAL_NED_DATA,
};
use std::time::Duration;

const IGNORE_POSITION: u16 = 0x7;
const IGNORE_ACCELERATION: u16 = 0x1c0;
const IGNORE_YAW: u16 = 0x400;
const IGNORE_YAW_RATE: u16 = 0x800;

/// A setpoint handed over by the control tick goes out when at least this fraction of the
/// period has passed, so that a control tick at exactly the stream rate never skips a beat
/// because of timer jitter. Re-sends between control ticks wait a full period.
const PERIOD_TOLERANCE: f64 = 0.75;

/// Encodes one setpoint in LOCAL_NED with the type mask that says which fields count.
pub fn encode(
    setpoint: &Setpoint,
    time_boot_ms: u32,
    target_system: u8,
    target_component: u8,
) -> SET_POSITION_TARGET_LOCAL_NED_DATA {
    let (position, velocity, yaw, base_mask) = match setpoint {
        Setpoint::Position {
            position_enu_m,
            velocity_ff_enu_mps,
            yaw,
        } => (
            *position_enu_m,
            *velocity_ff_enu_mps,
            *yaw,
            IGNORE_ACCELERATION,
        ),
        Setpoint::Velocity {
            velocity_enu_mps,
            yaw,
        } => (
            Vec3::zeros(),
            *velocity_enu_mps,
            *yaw,
            IGNORE_POSITION | IGNORE_ACCELERATION,
        ),
    };
    let (yaw_ned, yaw_rate_ned, yaw_mask) = match yaw {
        YawTarget::Angle(a) => (frames::yaw_enu_to_ned(a), 0.0, IGNORE_YAW_RATE),
        YawTarget::Rate(r) => (0.0, -r, IGNORE_YAW),
    };
    let [x, y, z] = frames::enu_to_ned(&position);
    let [vx, vy, vz] = frames::enu_to_ned(&velocity);
    SET_POSITION_TARGET_LOCAL_NED_DATA {
        time_boot_ms,
        x: x as f32,
        y: y as f32,
        z: z as f32,
        vx: vx as f32,
        vy: vy as f32,
        vz: vz as f32,
        afx: 0.0,
        afy: 0.0,
        afz: 0.0,
        yaw: yaw_ned as f32,
        yaw_rate: yaw_rate_ned as f32,
        type_mask: PositionTargetTypemask::from_bits_truncate(base_mask | yaw_mask),
        target_system,
        target_component,
        coordinate_frame: MavFrame::MAV_FRAME_LOCAL_NED,
    }
}

/// Paces the setpoint stream and refuses to re-send stale setpoints.
#[derive(Debug, Clone)]
pub struct SetpointStreamer {
    period: Duration,
    max_age: Duration,
    latest: Option<(Setpoint, Duration)>,
    last_sent: Option<Duration>,
    /// Start of the current uninterrupted run of sends.
    stream_since: Option<Duration>,
}

impl SetpointStreamer {
    pub fn new(period: Duration, max_age: Duration) -> Self {
        Self {
            period,
            max_age,
            latest: None,
            last_sent: None,
            stream_since: None,
        }
    }

    /// The control tick's output: a new setpoint, or `None` (nothing to command: stop).
    pub fn offer(&mut self, now: Duration, setpoint: Option<Setpoint>) {
        self.latest = setpoint.map(|s| (s, now));
    }

    /// Stops the stream at once (link lost, vehicle disarmed by the autopilot).
    pub fn stop(&mut self) {
        self.latest = None;
    }

    /// The setpoint to send now, if one is due and fresh. `from_control` is true right after
    /// the control tick offered it, false for the periodic re-send check.
    pub fn poll(&mut self, now: Duration, from_control: bool) -> Option<Setpoint> {
        let (setpoint, at) = self.latest?;
        if now.saturating_sub(at) > self.max_age {
            self.latest = None;
            return None;
        }
        let needed = if from_control {
            self.period.mul_f64(PERIOD_TOLERANCE)
        } else {
            self.period
        };
        let due = self
            .last_sent
            .is_none_or(|t| now.saturating_sub(t) >= needed);
        if !due {
            return None;
        }
        let continuous = self
            .last_sent
            .is_some_and(|t| now.saturating_sub(t) <= self.period * 2 + self.max_age);
        if !continuous {
            self.stream_since = Some(now);
        }
        self.last_sent = Some(now);
        Some(setpoint)
    }

    /// How long setpoints have streamed without a gap (zero when not streaming).
    pub fn streaming_for(&self, now: Duration) -> Duration {
        match (self.stream_since, self.last_sent, self.latest) {
            (Some(since), Some(last), Some(_))
                if now.saturating_sub(last) <= self.period * 2 + self.max_age =>
            {
                now.saturating_sub(since)
            }
            _ => Duration::ZERO,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: fn(u64) -> Duration = Duration::from_millis;

    fn hold(x: f64) -> Setpoint {
        Setpoint::Position {
            position_enu_m: Vec3::new(x, 5.0, 3.0),
            velocity_ff_enu_mps: Vec3::zeros(),
            yaw: YawTarget::Angle(0.0),
        }
    }

    #[test]
    fn position_setpoint_in_ned_with_mask() {
        let m = encode(&hold(10.0), 0, 1, 1);
        assert_eq!((m.x, m.y, m.z), (5.0, 10.0, -3.0));
        assert_eq!(m.type_mask.bits(), IGNORE_ACCELERATION | IGNORE_YAW_RATE);
        assert!((m.yaw - std::f32::consts::FRAC_PI_2).abs() < 1e-6);
        assert_eq!(m.coordinate_frame, MavFrame::MAV_FRAME_LOCAL_NED);
    }

    #[test]
    fn velocity_setpoint_with_yaw_rate() {
        let sp = Setpoint::Velocity {
            velocity_enu_mps: Vec3::new(1.0, 2.0, 0.5),
            yaw: YawTarget::Rate(0.3),
        };
        let m = encode(&sp, 0, 1, 1);
        assert_eq!((m.vx, m.vy, m.vz), (2.0, 1.0, -0.5));
        assert!((m.yaw_rate + 0.3).abs() < 1e-6);
        assert_eq!(
            m.type_mask.bits(),
            IGNORE_POSITION | IGNORE_ACCELERATION | IGNORE_YAW,
            "the mask PX4 and ArduPilot read as velocity + yaw rate"
        );
    }

    #[test]
    fn streams_at_the_period_and_stops_when_stale() {
        let mut s = SetpointStreamer::new(MS(20), MS(100));
        assert!(s.poll(MS(0), false).is_none(), "nothing offered");
        let mut sent = 0;
        for t in (0..200).step_by(10) {
            s.offer(MS(t), Some(hold(1.0)));
            if s.poll(MS(t), true).is_some() {
                sent += 1;
            }
            // The session's own 5 ms tick never sends early.
            assert!(s.poll(MS(t + 5), false).is_none());
        }
        assert_eq!(sent, 10, "a 100 Hz control tick gives a 50 Hz stream");
        assert!(s.streaming_for(MS(190)) >= MS(180));
        // The control loop stalls: re-sends continue only while the last setpoint is fresh.
        let resent = (200..400)
            .step_by(20)
            .filter(|t| s.poll(MS(*t), false).is_some())
            .count();
        assert_eq!(
            resent, 5,
            "the 190 ms setpoint is re-sent while younger than 100 ms"
        );
        assert!(s.poll(MS(400), false).is_none());
        assert_eq!(s.streaming_for(MS(400)), Duration::ZERO);
    }

    #[test]
    fn none_stops_the_stream_at_once() {
        let mut s = SetpointStreamer::new(MS(20), MS(100));
        s.offer(MS(0), Some(hold(1.0)));
        assert!(s.poll(MS(0), true).is_some());
        s.offer(MS(20), None);
        assert!(s.poll(MS(20), true).is_none());
    }

    #[test]
    fn jittery_ticks_at_the_stream_rate_never_skip() {
        let mut s = SetpointStreamer::new(MS(20), MS(100));
        let ticks = [0, 21, 39, 61, 79, 100, 119, 141];
        let sent = ticks
            .iter()
            .filter(|t| {
                s.offer(MS(**t), Some(hold(1.0)));
                s.poll(MS(**t), true).is_some()
            })
            .count();
        assert_eq!(sent, ticks.len());
    }
}
