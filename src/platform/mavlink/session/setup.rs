//! What the session asks of the autopilot once in contact (on first contact, after a reboot,
//! after a link loss): the profile's message rates, the fallback where they are refused, and
//! the EKF origin.
//!
//! In: the profile and the configured origin, the autopilot's answers. Out: COMMAND_LONGs,
//! REQUEST_DATA_STREAM and SET_GPS_GLOBAL_ORIGIN messages to send.

use super::Session;
use crate::platform::mavlink::commands::{CommandOutcome, CommandSpec};
use crate::platform::mavlink::legacy;
use crate::platform::mavlink::profile::IntervalFallback;
use mavlink::dialects::ardupilotmega::{MavCmd, MavResult};
use std::time::Duration;

/// SET_GPS_GLOBAL_ORIGIN is re-sent at this period until GPS_GLOBAL_ORIGIN confirms it.
const ORIGIN_PERIOD: Duration = Duration::from_secs(2);
const ORIGIN_ATTEMPTS: u8 = 10;
impl Session {
    /// Asks for the profile's message rates and sends the EKF origin: on first contact, after a
    /// reboot and after a link loss (ArduPilot's rates are per link and not saved).
    pub(super) fn configure(&mut self, now: Duration) {
        self.stream_setup.clear();
        self.stream_fallback_needed = false;
        let intervals = self.profile.message_intervals.clone();
        for (id, hz) in intervals {
            let spec = CommandSpec {
                command: MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL,
                params: [id as f32, (1e6 / hz) as f32, 0.0, 0.0, 0.0, 0.0, 0.0],
                target_component: 1,
            };
            self.stream_setup.push(self.tracker.submit(spec));
        }
        if self.config.ekf_origin.is_some() {
            self.origin_attempts = 0;
            self.next_origin_at = Some(now);
        }
    }

    /// Follows the answers to the message-rate requests; where the autopilot refused them and
    /// the profile says so, asks for every stream the old way (REQUEST_DATA_STREAM).
    pub(super) fn check_stream_setup(&mut self) {
        let mut remaining = Vec::new();
        for id in std::mem::take(&mut self.stream_setup) {
            match self.tracker.take_outcome(id) {
                None => remaining.push(id),
                Some(CommandOutcome::Accepted) => {}
                Some(CommandOutcome::Rejected {
                    result: MavResult::MAV_RESULT_UNSUPPORTED,
                    ..
                })
                | Some(CommandOutcome::TimedOut { .. }) => self.stream_fallback_needed = true,
                Some(other) => {
                    tracing::warn!(target: "mavlink", "message interval: {:?}", other);
                }
            }
        }
        self.stream_setup = remaining;
        let fallback =
            self.profile.message_interval_fallback == IntervalFallback::RequestDataStream;
        if self.stream_setup.is_empty()
            && std::mem::take(&mut self.stream_fallback_needed)
            && fallback
        {
            let rate = self
                .profile
                .message_intervals
                .iter()
                .map(|(_, hz)| *hz)
                .fold(1.0_f64, f64::max);
            if let Some((system, component)) = self.model.autopilot() {
                tracing::info!(target: "mavlink", "SET_MESSAGE_INTERVAL refused: REQUEST_DATA_STREAM at {rate} Hz");
                let rate_hz = rate.round().clamp(1.0, f64::from(u16::MAX)) as u16;
                self.push(legacy::request_all_streams(system, component, rate_hz));
            }
        }
    }

    /// Sends the configured EKF origin until the autopilot reports one, at most
    /// [`ORIGIN_ATTEMPTS`] times, every [`ORIGIN_PERIOD`].
    pub(super) fn send_origin(&mut self, now: Duration) {
        let (Some(origin), Some(at)) = (self.config.ekf_origin, self.next_origin_at) else {
            return;
        };
        if self.model.origin_seen() || self.origin_attempts >= ORIGIN_ATTEMPTS {
            self.next_origin_at = None;
            return;
        }
        if now < at {
            return;
        }
        let Some((system, _)) = self.model.autopilot() else {
            return;
        };
        self.origin_attempts += 1;
        self.next_origin_at = Some(now + ORIGIN_PERIOD);
        self.push(legacy::set_gps_global_origin(system, &origin));
    }
}
