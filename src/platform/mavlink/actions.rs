//! Platform requests as short step sequences: wait for readiness, command, confirm.
//!
//! In: a [`PlatformRequest`] (or an internal action such as "hold after the link came back"),
//! the profile, and each tick the vehicle model, the command tracker and the setpoint stream.
//! Out: commands for the tracker and, when the sequence ends, `Ok` or the autopilot's reason.
//! A mode change is done when HEARTBEAT shows the mode, not when the ack says ACCEPTED.

use super::commands::{CommandId, CommandOutcome, CommandSpec, CommandTracker};
use super::model::VehicleModel;
use super::profile::{
    AutopilotKind, GimbalProtocol, LandMethod, Mode, Profile, TakeoffAltitude, TakeoffMethod,
};
use super::setpoint::SetpointStreamer;
use crate::types::{PlatformRequest, RequestRefused};
use mavlink::dialects::ardupilotmega::{MavCmd, MavResult};
use std::collections::VecDeque;
use std::time::Duration;

/// Waiting for the setpoint stream before an offboard switch gives up after the prestream
/// time plus this.
const STREAM_WAIT_SLACK: Duration = Duration::from_secs(5);
/// Component id of the autopilot.
const AUTOPILOT_COMPONENT: u8 = 1;
/// MAV_MOUNT_MODE_MAVLINK_TARGETING.
const MOUNT_MODE_MAVLINK_TARGETING: f32 = 2.0;
/// GIMBAL_MANAGER_FLAGS_YAW_IN_VEHICLE_FRAME: yaw relative to the vehicle's heading.
const GIMBAL_YAW_IN_VEHICLE_FRAME: f32 = 32.0;

/// What the vehicle must show for a step to count as done.
#[derive(Debug, Clone, PartialEq)]
enum Condition {
    Mode(Mode),
    Armed(bool),
}

#[derive(Debug, Clone, PartialEq)]
enum Step {
    /// Until the autopilot can arm and fly offboard.
    WaitReady,
    /// Until setpoints have streamed for this long.
    WaitStream(Duration),
    /// Until the condition holds (without commanding anything), within the timeout.
    Await(Condition, Duration),
    /// Send a command; on ACCEPTED go on. `fallback` is tried once when the first is unsupported.
    Command {
        what: &'static str,
        spec: CommandSpec,
        fallback: Option<CommandSpec>,
    },
    /// Switch mode unless already there, then wait for HEARTBEAT to show it.
    SetMode(Mode),
}

/// What an action is for: a core request, or something the platform does on its own.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Origin {
    Request(PlatformRequest),
}

#[derive(Debug)]
enum Running {
    Idle,
    Waiting { since: Duration },
    Commanding { id: CommandId, fallback_used: bool },
    Confirming { since: Duration },
}

/// One request in progress.
#[derive(Debug)]
pub struct Action {
    pub origin: Origin,
    steps: VecDeque<Step>,
    running: Running,
}

/// Everything an action reads and drives on a tick.
pub struct Ctx<'a> {
    pub now: Duration,
    pub profile: &'a Profile,
    pub model: &'a VehicleModel,
    pub tracker: &'a mut CommandTracker,
    pub streamer: &'a SetpointStreamer,
}

fn spec(command: MavCmd, params: [f32; 7]) -> CommandSpec {
    CommandSpec {
        command,
        params,
        target_component: AUTOPILOT_COMPONENT,
    }
}

fn arm_spec(arm: bool) -> CommandSpec {
    let p1 = if arm { 1.0 } else { 0.0 };
    spec(
        MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
        [p1, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    )
}

/// MAV_MODE_FLAG_CUSTOM_MODE_ENABLED: DO_SET_MODE param 1.
const CUSTOM_MODE_ENABLED: f32 = 1.0;

fn set_mode_spec(profile: &Profile, mode: &Mode) -> CommandSpec {
    let (p2, p3) = profile.set_mode_params(mode);
    spec(
        MavCmd::MAV_CMD_DO_SET_MODE,
        [CUSTOM_MODE_ENABLED, p2, p3, 0.0, 0.0, 0.0, 0.0],
    )
}

/// Requests by which the core takes control of the vehicle (again, after a takeover): only an
/// operator's new order makes a behavior ask for them.
pub fn takes_control(request: PlatformRequest) -> bool {
    matches!(
        request,
        PlatformRequest::Arm
            | PlatformRequest::StartOffboard
            | PlatformRequest::Takeoff { .. }
            | PlatformRequest::Land
    )
}

/// The mode a request puts the vehicle in (`custom_mode`), when it changes the mode: what the
/// takeover watch expects to see after it (`takeover.rs`).
pub fn mode_of(request: PlatformRequest, profile: &Profile) -> Option<u32> {
    let roles = &profile.roles;
    match request {
        PlatformRequest::Arm if profile.arm_in_offboard_mode => Some(roles.offboard.custom_mode),
        PlatformRequest::StartOffboard => Some(roles.offboard.custom_mode),
        PlatformRequest::Land => Some(roles.land.custom_mode),
        PlatformRequest::Takeoff { .. } if profile.autopilot == AutopilotKind::Px4 => {
            roles.takeoff.as_ref().map(|m| m.custom_mode)
        }
        _ => None,
    }
}

/// NAV_TAKEOFF once armed (and, on ArduPilot, in the offboard mode), to the height above home
/// or its altitude AMSL as the profile says; then, on PX4, the takeoff mode confirmed.
fn takeoff_steps(
    height_m: f64,
    profile: &Profile,
    model: &VehicleModel,
) -> Result<Vec<Step>, RequestRefused> {
    let mut steps = Vec::new();
    let offboard = profile.roles.offboard.clone();
    if profile.takeoff != TakeoffMethod::NavTakeoff {
        return Err(RequestRefused(format!(
            "profile `{}` takes off on setpoints, not with NAV_TAKEOFF",
            profile.name
        )));
    }
    steps.push(Step::Await(
        Condition::Armed(true),
        profile.mode_confirm_timeout,
    ));
    if profile.autopilot == AutopilotKind::Ardupilot {
        steps.push(Step::Await(
            Condition::Mode(offboard),
            profile.mode_confirm_timeout,
        ));
    }
    let altitude = match profile.takeoff_altitude {
        TakeoffAltitude::Relative => height_m,
        TakeoffAltitude::Amsl => {
            let home = model.home_amsl_m().ok_or_else(|| {
                RequestRefused::from("takeoff needs the home altitude (HOME_POSITION) first")
            })?;
            home + height_m
        }
    };
    steps.push(Step::Command {
        what: "takeoff",
        spec: spec(
            MavCmd::MAV_CMD_NAV_TAKEOFF,
            [0.0, 0.0, 0.0, f32::NAN, f32::NAN, f32::NAN, altitude as f32],
        ),
        fallback: None,
    });
    if let (AutopilotKind::Px4, Some(m)) = (profile.autopilot, &profile.roles.takeoff) {
        steps.push(Step::Await(
            Condition::Mode(m.clone()),
            profile.mode_confirm_timeout,
        ));
    }
    Ok(steps)
}

/// The gimbal's pitch and yaw (FLU, rad) by the profile's protocol, with the legacy mount
/// command as the fallback of the gimbal manager's.
fn gimbal_step(pitch_rad: f64, yaw_rad: f64, profile: &Profile) -> Step {
    // FLU angles (pitch positive nose-down, yaw counter-clockwise) to MAVLink's FRD
    // degrees (pitch positive up, yaw clockwise).
    let pitch_deg = (-pitch_rad).to_degrees() as f32;
    let yaw_deg = (-yaw_rad).to_degrees() as f32;
    #[allow(deprecated)] // the legacy mount command is the fallback ArduPilot knows
    let mount = spec(
        MavCmd::MAV_CMD_DO_MOUNT_CONTROL,
        [
            pitch_deg,
            0.0,
            yaw_deg,
            0.0,
            0.0,
            0.0,
            MOUNT_MODE_MAVLINK_TARGETING,
        ],
    );
    let manager = spec(
        MavCmd::MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW,
        [
            pitch_deg,
            yaw_deg,
            f32::NAN,
            f32::NAN,
            GIMBAL_YAW_IN_VEHICLE_FRAME,
            0.0,
            0.0,
        ],
    );
    let (first, fallback) = match profile.gimbal {
        GimbalProtocol::ManagerV2 => (manager, Some(mount)),
        GimbalProtocol::MountControl => (mount, None),
    };
    Step::Command {
        what: "pointing the gimbal",
        spec: first,
        fallback,
    }
}

impl Action {
    /// Plans a request; `Err` when this profile cannot do it at all.
    pub fn plan(
        origin: Origin,
        request: PlatformRequest,
        profile: &Profile,
        model: &VehicleModel,
    ) -> Result<Self, RequestRefused> {
        let mut steps = VecDeque::new();
        let offboard = profile.roles.offboard.clone();
        match request {
            PlatformRequest::Arm => {
                steps.push_back(Step::WaitReady);
                if profile.arm_in_offboard_mode {
                    steps.push_back(Step::SetMode(offboard));
                }
                steps.push_back(Step::Command {
                    what: "arming",
                    spec: arm_spec(true),
                    fallback: None,
                });
                steps.push_back(Step::Await(
                    Condition::Armed(true),
                    profile.mode_confirm_timeout,
                ));
            }
            // Nothing to ask the autopilot: the session keeps it for the takeover watch.
            PlatformRequest::LandOnSetpoints => {}
            PlatformRequest::Disarm => {
                steps.push_back(Step::Command {
                    what: "disarming",
                    spec: arm_spec(false),
                    fallback: None,
                });
                steps.push_back(Step::Await(
                    Condition::Armed(false),
                    profile.mode_confirm_timeout,
                ));
            }
            PlatformRequest::StartOffboard => {
                if !profile.offboard_prestream.is_zero() {
                    steps.push_back(Step::WaitStream(profile.offboard_prestream));
                }
                steps.push_back(Step::SetMode(offboard));
            }
            PlatformRequest::Takeoff { height_m } => {
                steps.extend(takeoff_steps(height_m, profile, model)?);
            }
            PlatformRequest::Land => match profile.land {
                LandMethod::Mode | LandMethod::Setpoints => {
                    steps.push_back(Step::SetMode(profile.roles.land.clone()))
                }
                LandMethod::NavLand => {
                    steps.push_back(Step::Command {
                        what: "landing",
                        spec: spec(
                            MavCmd::MAV_CMD_NAV_LAND,
                            [0.0, 0.0, 0.0, f32::NAN, f32::NAN, f32::NAN, f32::NAN],
                        ),
                        fallback: None,
                    });
                    steps.push_back(Step::Await(
                        Condition::Mode(profile.roles.land.clone()),
                        profile.mode_confirm_timeout,
                    ));
                }
            },
            PlatformRequest::PointGimbal { pitch_rad, yaw_rad } => {
                steps.push_back(gimbal_step(pitch_rad, yaw_rad, profile));
            }
            PlatformRequest::TakePhoto => {
                steps.push_back(Step::Command {
                    what: "taking a photo",
                    spec: CommandSpec {
                        command: MavCmd::MAV_CMD_IMAGE_START_CAPTURE,
                        params: [0.0, 0.0, 1.0, 0.0, f32::NAN, f32::NAN, f32::NAN],
                        target_component: profile.camera_component,
                    },
                    fallback: None,
                });
            }
        }
        Ok(Self {
            origin,
            steps,
            running: Running::Idle,
        })
    }

    /// Switch to a mode (hold after the link returned, for example).
    pub fn set_mode(origin: Origin, mode: Mode) -> Self {
        Self {
            origin,
            steps: VecDeque::from([Step::SetMode(mode)]),
            running: Running::Idle,
        }
    }

    /// The request this action answers, if it came from the core.
    pub fn request(&self) -> Option<PlatformRequest> {
        match self.origin {
            Origin::Request(r) => Some(r),
        }
    }

    /// Drops the command in flight, if any (the action was superseded).
    pub fn abandon(&self, tracker: &mut CommandTracker) {
        if let Running::Commanding { id, .. } = self.running {
            tracker.forget(id);
        }
    }

    /// Advances; `Some` when finished.
    pub fn tick(&mut self, ctx: &mut Ctx) -> Option<Result<(), RequestRefused>> {
        // A few steps can complete in one tick (skipped mode changes, satisfied conditions).
        for _ in 0..8 {
            match self.advance(ctx) {
                Advance::Wait => return None,
                Advance::Fail(e) => return Some(Err(RequestRefused(e))),
                Advance::Next => {
                    self.steps.pop_front();
                    self.running = Running::Idle;
                    if self.steps.is_empty() {
                        return Some(Ok(()));
                    }
                }
            }
        }
        None
    }

    fn advance(&mut self, ctx: &mut Ctx) -> Advance {
        let Some(step) = self.steps.front().cloned() else {
            return Advance::Next;
        };
        let now = ctx.now;
        let since = match self.running {
            Running::Waiting { since } | Running::Confirming { since, .. } => since,
            _ => now,
        };
        let waited = now.saturating_sub(since);
        match step {
            Step::WaitReady => match ctx.model.readiness(now) {
                Ok(()) => Advance::Next,
                Err(reason) if waited >= ctx.profile.ready_timeout => Advance::Fail(format!(
                    "the autopilot is not ready after {:.0} s: {}",
                    waited.as_secs_f64(),
                    ctx.model
                        .last_problem()
                        .unwrap_or_else(|| reason.to_string())
                )),
                Err(_) => {
                    self.running = Running::Waiting { since };
                    Advance::Wait
                }
            },
            Step::WaitStream(needed) => {
                if ctx.streamer.streaming_for(now) >= needed {
                    Advance::Next
                } else if waited >= needed + STREAM_WAIT_SLACK {
                    Advance::Fail("no setpoint stream to enter offboard with".into())
                } else {
                    self.running = Running::Waiting { since };
                    Advance::Wait
                }
            }
            Step::Await(condition, timeout) => {
                if holds(&condition, ctx.model) {
                    Advance::Next
                } else if waited >= timeout {
                    Advance::Fail(describe_unmet(&condition, ctx))
                } else {
                    self.running = Running::Confirming { since };
                    Advance::Wait
                }
            }
            Step::SetMode(mode) => self.set_mode_step(ctx, mode),
            Step::Command {
                what,
                spec,
                fallback,
            } => self.command_step(ctx, what, spec, fallback),
        }
    }

    fn set_mode_step(&mut self, ctx: &mut Ctx, mode: Mode) -> Advance {
        let shown = ctx.model.custom_mode() == Some(mode.custom_mode);
        match self.running {
            Running::Idle if shown => Advance::Next,
            Running::Idle => {
                let id = ctx.tracker.submit(set_mode_spec(ctx.profile, &mode));
                self.running = Running::Commanding {
                    id,
                    fallback_used: false,
                };
                Advance::Wait
            }
            Running::Commanding { id, .. } => match ctx.tracker.take_outcome(id) {
                None => Advance::Wait,
                Some(CommandOutcome::Accepted) => {
                    self.running = Running::Confirming { since: ctx.now };
                    Advance::Wait
                }
                // Lost acks are common on lossy links: HEARTBEAT is the judge.
                Some(CommandOutcome::TimedOut { .. }) if shown => Advance::Next,
                Some(outcome) => Advance::Fail(
                    outcome
                        .into_result(&format!("switching to {}", mode.name))
                        .err()
                        .map(|e| e.0)
                        .unwrap_or_default(),
                ),
            },
            Running::Confirming { since, .. } | Running::Waiting { since } => {
                if shown {
                    Advance::Next
                } else if ctx.now.saturating_sub(since) >= ctx.profile.mode_confirm_timeout {
                    Advance::Fail(describe_unmet(&Condition::Mode(mode), ctx))
                } else {
                    Advance::Wait
                }
            }
        }
    }

    fn command_step(
        &mut self,
        ctx: &mut Ctx,
        what: &'static str,
        spec: CommandSpec,
        fallback: Option<CommandSpec>,
    ) -> Advance {
        match self.running {
            Running::Commanding { id, fallback_used } => match ctx.tracker.take_outcome(id) {
                None => Advance::Wait,
                Some(CommandOutcome::Accepted) => Advance::Next,
                Some(CommandOutcome::Rejected {
                    result: MavResult::MAV_RESULT_UNSUPPORTED,
                    ..
                }) if !fallback_used && fallback.is_some() => {
                    let Some(fb) = fallback else {
                        return Advance::Fail(format!("{what}: no fallback"));
                    };
                    self.running = Running::Commanding {
                        id: ctx.tracker.submit(fb),
                        fallback_used: true,
                    };
                    Advance::Wait
                }
                Some(outcome) => Advance::Fail(
                    outcome
                        .into_result(what)
                        .err()
                        .map(|e| e.0)
                        .unwrap_or_default(),
                ),
            },
            _ => {
                self.running = Running::Commanding {
                    id: ctx.tracker.submit(spec),
                    fallback_used: false,
                };
                Advance::Wait
            }
        }
    }
}

enum Advance {
    Wait,
    Next,
    Fail(String),
}

fn holds(condition: &Condition, model: &VehicleModel) -> bool {
    match condition {
        Condition::Mode(m) => model.custom_mode() == Some(m.custom_mode),
        Condition::Armed(a) => model.armed() == *a,
    }
}

fn describe_unmet(condition: &Condition, ctx: &Ctx) -> String {
    let reason = ctx
        .model
        .last_problem()
        .map(|r| format!(": {r}"))
        .unwrap_or_default();
    match condition {
        Condition::Mode(m) => format!(
            "the autopilot did not switch to {} (HEARTBEAT shows {}){reason}",
            m.name,
            ctx.model
                .custom_mode()
                .map_or_else(|| "nothing".into(), |c| ctx.profile.mode_name(c))
        ),
        Condition::Armed(true) => format!("the autopilot did not arm{reason}"),
        Condition::Armed(false) => format!("the autopilot did not disarm{reason}"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::platform::mavlink::testutil::{autopilot_header, hb, px4_profile};
    use mavlink::dialects::ardupilotmega::{MavMessage, COMMAND_ACK_DATA};

    const MS: fn(u64) -> Duration = Duration::from_millis;

    struct World {
        profile: Profile,
        model: VehicleModel,
        tracker: CommandTracker,
        streamer: SetpointStreamer,
    }

    impl World {
        fn new() -> Self {
            let profile = px4_profile();
            Self {
                model: VehicleModel::new(profile.clone(), None),
                tracker: CommandTracker::new(MS(500), 2),
                streamer: SetpointStreamer::new(MS(20), MS(100)),
                profile,
            }
        }
        fn tick(
            &mut self,
            a: &mut Action,
            now: Duration,
        ) -> (Option<Result<(), RequestRefused>>, usize) {
            let mut ctx = Ctx {
                now,
                profile: &self.profile,
                model: &self.model,
                tracker: &mut self.tracker,
                streamer: &self.streamer,
            };
            let r = a.tick(&mut ctx);
            let sent = self.tracker.poll(now, 1).len();
            (r, sent)
        }
        fn ack(&mut self, now: Duration, command: MavCmd, result: MavResult) {
            let ack = COMMAND_ACK_DATA {
                command,
                result,
                ..COMMAND_ACK_DATA::DEFAULT
            };
            self.tracker.on_ack(now, &ack, 1, 191);
        }
        fn heartbeat(&mut self, now: Duration, mode: u32, armed: bool) {
            self.model
                .ingest(now, &autopilot_header(), &hb(mode, armed));
        }
    }

    #[test]
    fn land_is_done_when_heartbeat_shows_the_mode_not_on_the_ack() {
        let mut w = World::new();
        w.heartbeat(MS(0), 0x0006_0000, true);
        let land = PlatformRequest::Land;
        let mut a = Action::plan(Origin::Request(land), land, &w.profile, &w.model).unwrap();
        assert_eq!(w.tick(&mut a, MS(0)), (None, 1));
        w.ack(
            MS(10),
            MavCmd::MAV_CMD_DO_SET_MODE,
            MavResult::MAV_RESULT_ACCEPTED,
        );
        assert_eq!(w.tick(&mut a, MS(20)).0, None, "accepted, not shown yet");
        w.heartbeat(MS(500), 0x0604_0000, true);
        assert_eq!(w.tick(&mut a, MS(500)).0, Some(Ok(())));
    }

    #[test]
    fn accepted_mode_change_that_never_shows_fails_with_the_mode_seen() {
        let mut w = World::new();
        w.heartbeat(MS(0), 0x0304_0000, true);
        let land = PlatformRequest::Land;
        let mut a = Action::plan(Origin::Request(land), land, &w.profile, &w.model).unwrap();
        w.tick(&mut a, MS(0));
        w.ack(
            MS(10),
            MavCmd::MAV_CMD_DO_SET_MODE,
            MavResult::MAV_RESULT_ACCEPTED,
        );
        w.tick(&mut a, MS(20));
        w.heartbeat(MS(2000), 0x0304_0000, true);
        let r = w.tick(&mut a, MS(3100)).0.unwrap().unwrap_err().to_string();
        assert!(
            r.contains("did not switch to AUTO.LAND (HEARTBEAT shows AUTO.LOITER)"),
            "{r}"
        );
    }

    #[test]
    fn offboard_waits_for_the_setpoint_stream() {
        let mut w = World::new();
        w.heartbeat(MS(0), 0x0304_0000, true);
        let req = PlatformRequest::StartOffboard;
        let mut a = Action::plan(Origin::Request(req), req, &w.profile, &w.model).unwrap();
        assert_eq!(
            w.tick(&mut a, MS(0)),
            (None, 0),
            "no stream: no mode command"
        );
        let sp = crate::types::Setpoint::Velocity {
            velocity_enu_mps: crate::types::Vec3::zeros(),
            yaw: crate::types::YawTarget::Rate(0.0),
        };
        let mut sent = 0;
        for t in (0..1300).step_by(20) {
            w.streamer.offer(MS(t), Some(sp));
            w.streamer.poll(MS(t), true);
            sent += w.tick(&mut a, MS(t)).1;
        }
        assert_eq!(sent, 1, "DO_SET_MODE after 1.2 s of stream");
    }

    #[test]
    fn arm_waits_for_readiness_then_fails_with_the_autopilot_reason() {
        let mut w = World::new();
        w.heartbeat(MS(0), 0x0304_0000, false);
        let req = PlatformRequest::Arm;
        let mut a = Action::plan(Origin::Request(req), req, &w.profile, &w.model).unwrap();
        assert_eq!(w.tick(&mut a, MS(0)), (None, 0));
        let ev = MavMessage::EVENT(mavlink::dialects::ardupilotmega::EVENT_DATA {
            id: 16_910_493,
            log_levels: 0x62,
            ..mavlink::dialects::ardupilotmega::EVENT_DATA::DEFAULT
        });
        w.model.ingest(MS(10), &autopilot_header(), &ev);
        for t in (1000..31_000).step_by(1000) {
            w.heartbeat(MS(t), 0x0304_0000, false);
        }
        let r = w
            .tick(&mut a, MS(30_500))
            .0
            .unwrap()
            .unwrap_err()
            .to_string();
        assert!(r.contains("Resolve system health failures"), "{r}");
    }
}
