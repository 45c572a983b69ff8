//! One autopilot session, without I/O: messages and control outputs in, messages out.
//!
//! In: decoded messages from the link ([`Session::on_message`]), each control tick's setpoint
//! and requests ([`Session::on_control`]), and a housekeeping tick ([`Session::on_tick`]), all
//! with the time; Kestrel's own texts for the ground station ([`Session::announce`]). Out: the
//! messages to send ([`Session::drain_outgoing`]: our HEARTBEAT at 1 Hz, as an onboard computer,
//! so ground stations list Kestrel; COMMAND_LONGs, setpoints, stream requests; STATUSTEXTs,
//! paced by [`Outbox`]) and the [`PlatformFeedback`] for the core. The
//! async transport in `link.rs` only moves bytes; tests and replay drive this directly.
//!
//! When the vehicle is taken from Kestrel (`takeover.rs`: a mode it did not ask for, a disarm in
//! the air), the session reports [`PlatformEvent::PilotTakeover`], drops its requests in
//! progress and sends no setpoint until the core asks for control again (arm, offboard, takeoff
//! or land: an operator's new order), so nothing Kestrel sends can fight the pilot.

mod requests;
mod setup;

use super::actions::{self, Action};
use super::commands::{CommandId, CommandTracker};
use super::model::{ModelEvent, VehicleModel};
use super::profile::{LandMethod, Profile, TakeoffMethod};
use super::setpoint::{self, SetpointStreamer};
use super::slew::Slew;
use super::statustext::{Outbox, StatusText};
use super::takeover::{ControlWatch, ModeReport, Takeover, WatchedModes};
use crate::platform::{
    Capabilities, PlatformEvent, PlatformFeedback, PlatformRequest, RequestResult,
};
use crate::types::GeoPoint;
use crate::types::LinkHealth;
use crate::types::{AcceptedSetpoints, Setpoint};
use mavlink::dialects::ardupilotmega::{
    MavAutopilot, MavMessage, MavModeFlag, MavState, MavType, HEARTBEAT_DATA,
};
use mavlink::MavHeader;
use serde::Serialize;
use std::net::SocketAddr;
use std::time::Duration;

const HEARTBEAT_PERIOD: Duration = Duration::from_secs(1);
const SILENCE_REPORT_PERIOD: Duration = Duration::from_secs(5);
/// The behavior `land` repeats [`PlatformRequest::LandOnSetpoints`] every tick: a landing not
/// heard of for this long has ended (stopped, or another behavior flies).
const LANDING_HINT_TTL: Duration = Duration::from_millis(500);

/// Settings of a session besides the profile.
#[derive(Debug, Clone, PartialEq)]
pub struct SessionConfig {
    /// Our system id; `None` = the vehicle's (PX4 counts companion heartbeats only from it).
    pub system_id: Option<u8>,
    /// Our component id (191 = MAV_COMP_ID_ONBOARD_COMPUTER).
    pub component_id: u8,
    /// Follow only this autopilot system id; `None` = the first one heard.
    pub target_system: Option<u8>,
    /// EKF origin sent with SET_GPS_GLOBAL_ORIGIN (indoors, without GPS).
    pub ekf_origin: Option<GeoPoint>,
}

impl Default for SessionConfig {
    fn default() -> Self {
        Self {
            system_id: None,
            component_id: 191,
            target_system: None,
            ekf_origin: None,
        }
    }
}

/// Counters for logs and benchmarks.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct SessionStats {
    pub messages_in: u64,
    pub setpoints_sent: u64,
    pub commands_sent: u64,
    pub link_losses: u64,
    /// Kestrel's texts dropped because too many waited (see [`Outbox`]).
    pub texts_dropped: u64,
}

pub struct Session {
    profile: Profile,
    config: SessionConfig,
    model: VehicleModel,
    tracker: CommandTracker,
    streamer: SetpointStreamer,
    actions: Vec<Action>,
    results: Vec<RequestResult>,
    outgoing: Vec<(MavHeader, MavMessage)>,
    next_heartbeat: Duration,
    stream_setup: Vec<CommandId>,
    stream_fallback_needed: bool,
    origin_attempts: u8,
    next_origin_at: Option<Duration>,
    /// While the link is down: when to report again what still arrives.
    next_silence_report: Option<Duration>,
    link_was_lost: bool,
    /// Whether Kestrel or someone else flies the vehicle.
    watch: ControlWatch,
    /// The vehicle was taken from Kestrel: no setpoints until the core asks for control again.
    handed_over: bool,
    last_setpoint_at: Option<Duration>,
    /// How fast the velocity sent may change (the profile's `[drive] command_slew_mps2`).
    slew: Option<Slew>,
    events: Vec<PlatformEvent>,
    texts: Outbox,
    /// When the behavior `land` last said it flies the descent on setpoints.
    landing_on_setpoints_at: Option<Duration>,
    /// `udpin`: the autopilot's pinned address and how many times another took its place.
    peer: Option<(SocketAddr, u32)>,
    stats: SessionStats,
}

impl Session {
    pub fn new(profile: Profile, config: SessionConfig) -> Self {
        let roles = &profile.roles;
        let watch = ControlWatch::new(WatchedModes {
            offboard: roles.offboard.custom_mode,
            land: roles.land.custom_mode,
            hold: roles.hold.custom_mode,
            takeoff: roles.takeoff.as_ref().map(|m| m.custom_mode),
        });
        Self {
            watch,
            handed_over: false,
            last_setpoint_at: None,
            slew: profile.command_slew_mps2.map(Slew::new),
            events: Vec::new(),
            model: VehicleModel::new(profile.clone(), config.target_system),
            tracker: CommandTracker::new(profile.command_timeout, profile.command_retries),
            streamer: SetpointStreamer::new(profile.setpoint_period, profile.setpoint_max_age),
            profile,
            config,
            actions: Vec::new(),
            results: Vec::new(),
            outgoing: Vec::new(),
            next_heartbeat: Duration::ZERO,
            stream_setup: Vec::new(),
            stream_fallback_needed: false,
            origin_attempts: 0,
            next_origin_at: None,
            next_silence_report: None,
            link_was_lost: false,
            texts: Outbox::default(),
            landing_on_setpoints_at: None,
            peer: None,
            stats: SessionStats::default(),
        }
    }

    pub fn capabilities(&self) -> Capabilities {
        Capabilities {
            setpoints: AcceptedSetpoints {
                velocity: true,
                position: true,
                position_loop: self.profile.position_loop,
            },
            native_takeoff: self.profile.takeoff == TakeoffMethod::NavTakeoff,
            native_land: self.profile.land != LandMethod::Setpoints,
            velocity_lag_s: Some(self.profile.velocity_lag.as_secs_f64()),
            velocity_overshoot: self.profile.velocity_overshoot,
            yaw_rate_overshoot: self.profile.yaw_rate_overshoot,
            height_error_m: self.profile.height_error_m,
        }
    }

    pub fn model(&self) -> &VehicleModel {
        &self.model
    }

    pub fn stats(&self) -> SessionStats {
        self.stats
    }

    fn our_system(&self) -> Option<u8> {
        self.config
            .system_id
            .or_else(|| self.model.autopilot().map(|(s, _)| s))
    }

    fn push(&mut self, msg: MavMessage) {
        if let Some(system) = self.our_system() {
            let header = MavHeader {
                system_id: u32::from(system),
                component_id: self.config.component_id,
                sequence: 0,
            };
            self.outgoing.push((header, msg));
        }
    }

    /// Messages to send, in order.
    pub fn drain_outgoing(&mut self) -> Vec<(MavHeader, MavMessage)> {
        std::mem::take(&mut self.outgoing)
    }

    /// Texts waiting to go out (paced, or waiting for the link).
    pub fn texts_waiting(&self) -> usize {
        self.texts.len()
    }

    /// A text for the ground station (sent as STATUSTEXT, paced, while the link is up).
    pub fn announce(&mut self, text: StatusText) {
        if !self.texts.push(text) {
            self.stats.texts_dropped = self.texts.dropped();
            if self.stats.texts_dropped.is_power_of_two() {
                tracing::warn!(
                    target: "mavlink",
                    "{} texts for the ground station dropped (too many at once)",
                    self.stats.texts_dropped
                );
            }
        }
    }

    /// The transport failed (connect or read error): visible in the status until the link is up.
    pub fn note_transport_error(&mut self, error: String) {
        self.model.set_error(format!("connection: {error}"));
    }

    /// The transport pinned the autopilot's address (`udpin`): shown in the status; a change
    /// of address is also the last error, so operators hear of it.
    pub fn note_peer(&mut self, address: SocketAddr, previous: Option<SocketAddr>, changes: u32) {
        self.peer = Some((address, changes));
        if let Some(old) = previous {
            self.model.set_error(format!(
                "the autopilot is now answered at {address}, no longer at {old} (address change \
                 {changes}, after its silence)"
            ));
        }
    }

    /// One message from the link.
    pub fn on_message(&mut self, now: Duration, header: &MavHeader, msg: &MavMessage) {
        self.stats.messages_in += 1;
        let was_airborne = self.model.airborne();
        let event = self.model.ingest(now, header, msg);
        if matches!(event, Some(ModelEvent::Rebooted)) {
            self.watch.link_lost();
        }
        let mode_report = matches!(msg, MavMessage::HEARTBEAT(_) | MavMessage::CURRENT_MODE(_));
        if mode_report && self.model.is_from_autopilot(header) {
            self.watch_mode(now, was_airborne);
        }
        if let MavMessage::COMMAND_ACK(ack) = msg {
            if self
                .model
                .autopilot()
                .is_some_and(|(s, _)| u32::from(s) == header.system_id)
            {
                let ours = self.our_system().unwrap_or(0);
                self.tracker
                    .on_ack(now, ack, ours, self.config.component_id);
            }
        }
        match event {
            Some(ModelEvent::Text(text)) => {
                tracing::info!(target: "mavlink", "autopilot: {}", text.text);
                self.tracker.on_text(&text);
            }
            Some(ModelEvent::Contact {
                system_id,
                component_id,
            }) => {
                tracing::info!(
                    target: "mavlink",
                    "autopilot {system_id}/{component_id} heard ({})",
                    self.profile.name
                );
                self.configure(now);
                if std::mem::take(&mut self.link_was_lost) {
                    self.link_regained();
                }
            }
            Some(ModelEvent::Rebooted) => {
                tracing::warn!(target: "mavlink", "the autopilot rebooted");
                self.fail_all("the autopilot rebooted");
                self.configure(now);
            }
            None => {}
        }
    }

    /// The control tick's outputs: the setpoint (`None`: nothing to command) and requests.
    pub fn on_control(
        &mut self,
        now: Duration,
        setpoint: Option<Setpoint>,
        requests: &[PlatformRequest],
    ) {
        if requests.iter().any(|r| actions::takes_control(*r)) {
            self.handed_over = false;
        }
        let link_ok = self.model.link(now) == LinkHealth::Ok;
        let setpoint = setpoint.filter(|_| link_ok && !self.handed_over);
        self.streamer.offer(now, setpoint);
        for r in requests {
            self.request(now, *r);
        }
        self.stream_setpoint(now, true);
    }

    /// A mode report arrived: was the vehicle taken from Kestrel?
    fn watch_mode(&mut self, now: Duration, was_airborne: bool) {
        let Some(custom_mode) = self.model.custom_mode() else {
            return;
        };
        let report = ModeReport {
            custom_mode,
            armed: self.model.armed(),
            was_airborne,
        };
        let landing = self
            .landing_on_setpoints_at
            .is_some_and(|t| now.saturating_sub(t) <= LANDING_HINT_TTL);
        self.watch.landing_on_setpoints(landing);
        let Some(takeover) = self.watch.report(report) else {
            return;
        };
        let event = PlatformEvent::PilotTakeover {
            mode: self.profile.mode_name(custom_mode),
            disarmed: takeover == Takeover::Disarmed,
        };
        let reason = event.reason();
        // A takeover shortly after Kestrel's setpoints stopped may be PX4's offboard-loss
        // failsafe rather than a person: the log says which, the outcome is the same.
        let last_setpoint = self.last_setpoint_at.map_or_else(
            || "never".to_string(),
            |t| format!("{:.2} s ago", (now - t).as_secs_f64()),
        );
        tracing::warn!(
            target: "mavlink",
            "{reason}: Kestrel stops commanding the vehicle (last setpoint sent {last_setpoint})"
        );
        self.handed_over = true;
        self.streamer.stop();
        self.cancel(|_| true, &reason);
        self.model.set_error(reason);
        self.events.push(event);
    }

    /// Timers: link health, heartbeat, retries, actions, stream re-sends.
    pub fn on_tick(&mut self, now: Duration) {
        if self.model.check_link(now) {
            tracing::warn!(
                target: "mavlink",
                "link to the autopilot lost (nothing for {:?}; {} messages so far)",
                self.profile.heartbeat_timeout,
                self.stats.messages_in
            );
            self.next_silence_report = Some(now + SILENCE_REPORT_PERIOD);
            self.stats.link_losses += 1;
            self.link_was_lost = true;
            self.watch.link_lost();
            self.streamer.stop();
            self.fail_all("link to the autopilot lost");
        }
        let link_ok = self.model.link(now) == LinkHealth::Ok;
        if link_ok {
            self.next_silence_report = None;
        } else if self.next_silence_report.is_some_and(|t| now >= t) {
            // Tells a dead transport (nothing arrives) from a silent autopilot (other traffic).
            tracing::warn!(
                target: "mavlink",
                "still no link: {} messages received so far",
                self.stats.messages_in
            );
            self.next_silence_report = Some(now + SILENCE_REPORT_PERIOD);
        }
        if now >= self.next_heartbeat && self.our_system().is_some() {
            self.next_heartbeat = now + HEARTBEAT_PERIOD;
            self.push(our_heartbeat());
        }
        if link_ok {
            self.send_origin(now);
            self.run_actions(now);
            self.check_stream_setup();
            if self.our_system().is_some() {
                for text in self.texts.poll(now) {
                    self.push(MavMessage::STATUSTEXT(text));
                }
            }
            if let Some((system, _)) = self.model.autopilot() {
                for cmd in self.tracker.poll(now, system) {
                    self.stats.commands_sent += 1;
                    self.push(MavMessage::COMMAND_LONG(cmd));
                }
            }
        }
        self.stream_setpoint(now, false);
    }

    /// Status, the latest odometry, scans and finished requests since the last call.
    pub fn feedback(&mut self, now: Duration) -> PlatformFeedback {
        let mut status = self.model.status(now);
        if let Some((address, changes)) = self.peer {
            status.autopilot_address = Some(address.to_string());
            status.autopilot_address_changes = changes;
        }
        PlatformFeedback {
            status,
            measurements: self.model.odometry(now).into_iter().collect(),
            scans: self.model.take_scans(),
            request_results: std::mem::take(&mut self.results),
            virtual_collision: None,
            events: std::mem::take(&mut self.events),
        }
    }

    fn stream_setpoint(&mut self, now: Duration, from_control: bool) {
        if self.model.link(now) != LinkHealth::Ok {
            return;
        }
        let Some((system, component)) = self.model.autopilot() else {
            return;
        };
        if let Some(sp) = self.streamer.poll(now, from_control) {
            let boot_ms = u32::try_from(now.as_millis()).unwrap_or(u32::MAX);
            self.stats.setpoints_sent += 1;
            self.last_setpoint_at = Some(now);
            let sp = match (sp, self.slew.as_mut()) {
                (
                    Setpoint::Velocity {
                        velocity_enu_mps,
                        yaw,
                    },
                    Some(slew),
                ) => Setpoint::Velocity {
                    velocity_enu_mps: slew.limit(now, velocity_enu_mps),
                    yaw,
                },
                (sp, _) => sp,
            };
            let sp = sp.with_velocity_added(self.model.velocity_bias_enu_mps());
            let msg = setpoint::encode(&sp, boot_ms, system, component);
            self.push(MavMessage::SET_POSITION_TARGET_LOCAL_NED(msg));
        }
    }

    /// The link is back: the platform does nothing by itself. The mission executor decides
    /// (`[mission] on_link_regained`), and a behavior it starts asks for offboard again.
    fn link_regained(&mut self) {
        if self.model.armed() {
            tracing::info!(target: "mavlink", "link back while armed");
        }
    }
}

fn our_heartbeat() -> MavMessage {
    MavMessage::HEARTBEAT(HEARTBEAT_DATA {
        custom_mode: 0,
        mavtype: MavType::MAV_TYPE_ONBOARD_CONTROLLER,
        autopilot: MavAutopilot::MAV_AUTOPILOT_INVALID,
        base_mode: MavModeFlag::empty(),
        system_status: MavState::MAV_STATE_ACTIVE,
        mavlink_version: 3,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::platform::mavlink::testutil::{autopilot_header, hb, px4_profile};
    use crate::types::Vec3;
    use crate::types::YawTarget;
    use mavlink::dialects::ardupilotmega::COMMAND_ACK_DATA;
    use mavlink::dialects::ardupilotmega::{MavCmd, MavResult};
    use mavlink::Message;

    const MS: fn(u64) -> Duration = Duration::from_millis;

    fn names(out: &[(MavHeader, MavMessage)]) -> Vec<&'static str> {
        out.iter().map(|(_, m)| m.message_name()).collect()
    }

    fn sp() -> Setpoint {
        Setpoint::Position {
            position_enu_m: Vec3::new(0.0, 0.0, 3.0),
            velocity_ff_enu_mps: Vec3::zeros(),
            yaw: YawTarget::Angle(0.0),
        }
    }

    #[test]
    fn silent_until_the_vehicle_is_heard_then_heartbeat_and_intervals() {
        let mut s = Session::new(px4_profile(), SessionConfig::default());
        s.on_tick(MS(0));
        assert!(
            s.drain_outgoing().is_empty(),
            "our system id is the vehicle's: unknown yet"
        );
        s.on_message(MS(10), &autopilot_header(), &hb(0x0304_0000, false));
        s.on_tick(MS(20));
        let out = s.drain_outgoing();
        assert_eq!(out[0].1.message_name(), "HEARTBEAT");
        assert_eq!(out[0].0.system_id, 1);
        assert_eq!(out[0].0.component_id, 191);
        let MavMessage::HEARTBEAT(ours) = &out[0].1 else {
            panic!("{:?}", out[0].1);
        };
        // What QGroundControl lists as an onboard computer, not a second vehicle.
        assert_eq!(ours.mavtype, MavType::MAV_TYPE_ONBOARD_CONTROLLER);
        assert_eq!(ours.autopilot, MavAutopilot::MAV_AUTOPILOT_INVALID);
        assert!(names(&out).contains(&"COMMAND_LONG"), "{:?}", names(&out));
    }

    #[test]
    fn texts_wait_for_the_link_then_go_out_as_statustext_from_our_component() {
        use crate::platform::mavlink::statustext::{Severity, StatusText};
        let mut s = Session::new(px4_profile(), SessionConfig::default());
        let long = "go_to #2 started (position=[10.0, 0.0, 5.0], speed=2)";
        s.announce(StatusText {
            severity: Severity::Info,
            text: long.into(),
        });
        s.on_tick(MS(0));
        assert!(s.drain_outgoing().is_empty(), "no autopilot yet");
        s.on_message(MS(10), &autopilot_header(), &hb(0x0304_0000, false));
        s.on_tick(MS(20));
        let texts: Vec<_> = s
            .drain_outgoing()
            .into_iter()
            .filter_map(|(h, m)| match m {
                MavMessage::STATUSTEXT(t) => Some((h, t)),
                _ => None,
            })
            .collect();
        assert_eq!(texts.len(), 2, "9 + 53 bytes: two chunks");
        assert!(texts
            .iter()
            .all(|(h, t)| (h.system_id, h.component_id, t.id) == (1, 191, 1)));
        let bytes: Vec<u8> = texts.iter().flat_map(|(_, t)| t.text.to_vec()).collect();
        let text = String::from_utf8_lossy(&bytes);
        assert!(text.starts_with(&format!("Kestrel: {long}\0")), "{text}");
    }

    #[test]
    fn the_pinned_address_and_a_change_of_it_show_in_the_status() {
        let mut s = Session::new(px4_profile(), SessionConfig::default());
        let status = s.feedback(MS(0)).status;
        assert_eq!((status.autopilot_address, status.last_error), (None, None));
        let (first, moved) = (
            "127.0.0.1:14580".parse().unwrap(),
            "127.0.0.1:14581".parse().unwrap(),
        );
        s.note_peer(first, None, 0);
        let status = s.feedback(MS(10)).status;
        assert_eq!(status.autopilot_address.as_deref(), Some("127.0.0.1:14580"));
        assert_eq!(
            (status.autopilot_address_changes, status.last_error),
            (0, None)
        );
        s.note_peer(moved, Some(first), 1);
        let status = s.feedback(MS(20)).status;
        assert_eq!(status.autopilot_address.as_deref(), Some("127.0.0.1:14581"));
        assert_eq!(status.autopilot_address_changes, 1);
        let error = status.last_error.unwrap_or_default();
        assert!(
            error.contains("127.0.0.1:14581") && error.contains("127.0.0.1:14580"),
            "{error}"
        );
    }

    #[test]
    fn setpoints_stream_only_with_a_link_and_a_fresh_setpoint() {
        let mut s = Session::new(px4_profile(), SessionConfig::default());
        s.on_control(MS(0), Some(sp()), &[]);
        assert!(s.drain_outgoing().is_empty(), "no autopilot yet");
        s.on_message(MS(0), &autopilot_header(), &hb(0x0006_0000, true));
        s.drain_outgoing();
        s.on_control(MS(20), Some(sp()), &[]);
        assert_eq!(
            names(&s.drain_outgoing()),
            vec!["SET_POSITION_TARGET_LOCAL_NED"]
        );
        // The control loop stalls: re-sent while fresh, then silence.
        let mut resent = 0;
        for t in (40..400).step_by(20) {
            s.on_tick(MS(t));
            resent += names(&s.drain_outgoing())
                .iter()
                .filter(|n| **n == "SET_POSITION_TARGET_LOCAL_NED")
                .count();
        }
        assert_eq!(resent, 5, "only within the 100 ms maximum age");
        // Link lost: nothing goes out even with fresh setpoints.
        s.on_tick(MS(2000));
        s.drain_outgoing();
        s.on_control(MS(2010), Some(sp()), &[]);
        assert!(s.drain_outgoing().is_empty());
        assert_eq!(s.feedback(MS(2010)).status.link, LinkHealth::Lost);
    }

    #[test]
    fn arm_is_sent_tracked_and_reported_once() {
        let mut s = Session::new(px4_profile(), SessionConfig::default());
        s.on_message(MS(0), &autopilot_header(), &hb(0x0304_0000, false));
        let lp = MavMessage::LOCAL_POSITION_NED(
            mavlink::dialects::ardupilotmega::LOCAL_POSITION_NED_DATA::DEFAULT,
        );
        s.on_message(MS(0), &autopilot_header(), &lp);
        s.on_control(MS(1), None, &[PlatformRequest::Arm, PlatformRequest::Arm]);
        s.on_tick(MS(2));
        let arms = s
            .drain_outgoing()
            .into_iter()
            .filter(|(_, m)| matches!(m, MavMessage::COMMAND_LONG(c) if c.command == MavCmd::MAV_CMD_COMPONENT_ARM_DISARM))
            .count();
        assert_eq!(arms, 1, "duplicates are ignored while in progress");
        let ack = MavMessage::COMMAND_ACK(COMMAND_ACK_DATA {
            command: MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
            result: MavResult::MAV_RESULT_ACCEPTED,
            ..COMMAND_ACK_DATA::DEFAULT
        });
        s.on_message(MS(10), &autopilot_header(), &ack);
        s.on_message(MS(20), &autopilot_header(), &hb(0x0304_0000, true));
        s.on_tick(MS(30));
        let fb = s.feedback(MS(30));
        assert_eq!(
            fb.request_results,
            vec![RequestResult {
                request: PlatformRequest::Arm,
                outcome: Ok(())
            }]
        );
        assert!(fb.status.armed);
    }

    fn commands_sent(s: &mut Session) -> Vec<(MavCmd, u8, [f32; 7])> {
        s.drain_outgoing()
            .into_iter()
            .filter_map(|(_, m)| match m {
                MavMessage::COMMAND_LONG(c) => Some((
                    c.command,
                    c.target_component,
                    [
                        c.param1, c.param2, c.param3, c.param4, c.param5, c.param6, c.param7,
                    ],
                )),
                _ => None,
            })
            .filter(|(c, _, _)| *c != MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL)
            .collect()
    }

    fn ack(command: MavCmd, result: MavResult) -> MavMessage {
        MavMessage::COMMAND_ACK(COMMAND_ACK_DATA {
            command,
            result,
            ..COMMAND_ACK_DATA::DEFAULT
        })
    }

    #[test]
    fn a_mode_change_kestrel_did_not_ask_for_is_reported_and_ends_the_stream() {
        use crate::platform::PlatformEvent;
        use mavlink::dialects::ardupilotmega::{
            MavLandedState, CURRENT_MODE_DATA, EXTENDED_SYS_STATE_DATA,
        };
        const OFFBOARD: u32 = 0x0006_0000;
        const LOITER: u32 = 0x0304_0000;
        let h = autopilot_header();
        let mut s = Session::new(px4_profile(), SessionConfig::default());
        let in_air = MavMessage::EXTENDED_SYS_STATE(EXTENDED_SYS_STATE_DATA {
            landed_state: MavLandedState::MAV_LANDED_STATE_IN_AIR,
            ..EXTENDED_SYS_STATE_DATA::DEFAULT
        });
        s.on_message(MS(0), &h, &hb(OFFBOARD, true));
        s.on_message(MS(0), &h, &in_air);
        s.on_control(MS(10), Some(sp()), &[]);
        assert_eq!(
            names(&s.drain_outgoing()),
            ["SET_POSITION_TARGET_LOCAL_NED"]
        );
        assert!(s.feedback(MS(10)).events.is_empty());
        // A ground station switches PX4 to AUTO.LOITER: CURRENT_MODE says so at once.
        let loiter = MavMessage::CURRENT_MODE(CURRENT_MODE_DATA {
            custom_mode: LOITER,
            intended_custom_mode: LOITER,
            ..CURRENT_MODE_DATA::DEFAULT
        });
        s.on_message(MS(20), &h, &loiter);
        let fb = s.feedback(MS(20));
        assert_eq!(
            fb.events,
            [PlatformEvent::PilotTakeover {
                mode: "AUTO.LOITER".into(),
                disarmed: false
            }]
        );
        assert_eq!(
            fb.status.last_error.as_deref(),
            Some("pilot took over (mode AUTO.LOITER)")
        );
        // Nothing goes out, even a setpoint offered before the core heard of it.
        for t in (30..300).step_by(10) {
            s.on_control(MS(t), Some(sp()), &[]);
            s.on_tick(MS(t + 5));
        }
        let commanding: Vec<MavMessage> = s
            .drain_outgoing()
            .into_iter()
            .map(|(_, m)| m)
            .filter(|m| match m {
                MavMessage::COMMAND_LONG(c) => c.command != MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL,
                MavMessage::HEARTBEAT(_) => false,
                _ => true,
            })
            .collect();
        assert!(commanding.is_empty(), "{commanding:?}");
        s.on_message(MS(300), &h, &hb(LOITER, true));
        assert!(s.feedback(MS(300)).events.is_empty(), "reported once");
        // An operator's order (RESUME) takes it back: setpoints, then OFFBOARD again.
        s.on_control(MS(310), Some(sp()), &[PlatformRequest::StartOffboard]);
        assert_eq!(
            names(&s.drain_outgoing()),
            ["SET_POSITION_TARGET_LOCAL_NED"]
        );
        s.on_message(MS(2000), &h, &hb(OFFBOARD, true));
        s.on_message(MS(2100), &h, &hb(LOITER, true));
        assert_eq!(s.feedback(MS(2100)).events.len(), 1, "Kestrel's again");
    }

    #[test]
    fn gimbal_falls_back_to_mount_control_and_photo_waits_for_its_ack() {
        let mut s = Session::new(px4_profile(), SessionConfig::default());
        s.on_message(MS(0), &autopilot_header(), &hb(0x0304_0000, true));
        let point = PlatformRequest::PointGimbal {
            pitch_rad: 0.5,
            yaw_rad: 0.25,
        };
        s.on_control(MS(1), None, &[point, PlatformRequest::TakePhoto]);
        s.on_tick(MS(2));
        let sent = commands_sent(&mut s);
        let (cmd, comp, p) = sent[0];
        assert_eq!(cmd, MavCmd::MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW);
        assert_eq!(comp, 1);
        // FLU pitch 0.5 rad (nose down) is -28.6 deg in MAVLink; FLU yaw left is negative.
        assert!(
            (p[0] + 28.648).abs() < 0.01 && (p[1] + 14.324).abs() < 0.01,
            "{p:?}"
        );
        assert_eq!(sent[1].0, MavCmd::MAV_CMD_IMAGE_START_CAPTURE);
        assert_eq!(sent[1].1, 100, "the camera component");
        let h = autopilot_header();
        s.on_message(
            MS(10),
            &h,
            &ack(
                MavCmd::MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW,
                MavResult::MAV_RESULT_UNSUPPORTED,
            ),
        );
        s.on_message(
            MS(10),
            &h,
            &ack(
                MavCmd::MAV_CMD_IMAGE_START_CAPTURE,
                MavResult::MAV_RESULT_ACCEPTED,
            ),
        );
        s.on_tick(MS(400));
        s.on_tick(MS(401));
        let sent = commands_sent(&mut s);
        #[allow(deprecated)]
        let mount = MavCmd::MAV_CMD_DO_MOUNT_CONTROL;
        assert_eq!(sent.first().map(|c| c.0), Some(mount), "{sent:?}");
        s.on_message(MS(410), &h, &ack(mount, MavResult::MAV_RESULT_ACCEPTED));
        s.on_tick(MS(411));
        let results = s.feedback(MS(411)).request_results;
        assert_eq!(
            results,
            vec![
                RequestResult {
                    request: PlatformRequest::TakePhoto,
                    outcome: Ok(())
                },
                RequestResult {
                    request: point,
                    outcome: Ok(())
                },
            ]
        );
    }
}
