//! `takeoff`: arm, enter offboard, climb `height` metres above the ground at `speed`.

use super::goal::{check_positive, GoalError};
use super::progress::Progress;
use super::registry::{BehaviorSpec, Goal, Resource};
use super::server::seconds_since;
use super::{Behavior, BehaviorContext, Failure, FailureCode, Step};
use crate::control::MotionReference;
use crate::types::PlatformRequest;
use crate::types::{FlightStatus, LinkHealth, Vec3};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};
use serde_json::json;
use std::time::Duration;

#[derive(Debug, Clone, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct TakeoffGoal {
    /// Height above the takeoff point (m).
    #[serde(default = "default_height")]
    pub height: f64,
    /// Climb speed (m/s).
    #[serde(default = "default_speed")]
    pub speed: f64,
}

fn default_height() -> f64 {
    1.0
}
fn default_speed() -> f64 {
    0.5
}

impl Goal for TakeoffGoal {
    fn check(&self) -> Result<(), GoalError> {
        check_positive("height", self.height, "metres")?;
        check_positive("speed", self.speed, "m/s")
    }
    fn speeds_mps(&self) -> Vec<f64> {
        vec![self.speed]
    }
    fn heights_m(&self) -> Vec<f64> {
        vec![self.height]
    }
}

pub fn spec() -> BehaviorSpec {
    BehaviorSpec::new(
        "takeoff",
        "Arm, enter offboard and climb to a height above the takeoff point",
        Resource::Motion,
        Takeoff::new,
    )
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Phase {
    /// Waiting for the vehicle to be ready (link up, position estimate, autopilot checks).
    WaitReady {
        since: Option<Duration>,
    },
    Arming {
        since: Option<Duration>,
        last_request: Option<Duration>,
    },
    Climbing,
}

pub struct Takeoff {
    goal: TakeoffGoal,
    phase: Phase,
    /// Hold point on the ground while arming, then the climb target.
    target: Vec3,
    yaw_rad: f64,
    /// How the climb gets on (from the first tick in the air).
    climb: Option<Progress>,
    /// The autopilot's own climb (NAV_TAKEOFF) stopped short: Kestrel finishes it on setpoints.
    finishing: bool,
    /// When NAV_TAKEOFF was last asked for (the autopilot's own takeoff).
    takeoff_asked_at: Option<Duration>,
}

/// An autopilot climb that has not got on for this long is finished on Kestrel's setpoints (s).
const NATIVE_STALL_S: f64 = 3.0;

/// Re-send arm/offboard requests at this period until the platform shows them.
const REQUEST_PERIOD: Duration = Duration::from_secs(1);

impl Takeoff {
    pub(crate) fn new(goal: TakeoffGoal) -> Self {
        Self {
            goal,
            phase: Phase::WaitReady { since: None },
            target: Vec3::zeros(),
            yaw_rad: 0.0,
            climb: None,
            finishing: false,
            takeoff_asked_at: None,
        }
    }
}

impl Takeoff {
    /// Climb target and heading from where the vehicle sits now.
    fn capture_start(&mut self, ctx: &BehaviorContext) {
        let p = ctx.position();
        self.target = Vec3::new(p.x, p.y, p.z + self.goal.height);
        self.yaw_rad = ctx.yaw();
    }
}

impl Behavior for Takeoff {
    fn goal_enu_m(&self) -> Option<Vec3> {
        Some(self.target)
    }

    fn activate(&mut self, ctx: &BehaviorContext) -> Result<(), Failure> {
        if ctx.platform.flight.is_airborne() {
            return Err(Failure::invalid("already flying"));
        }
        if ctx.platform.flight == FlightStatus::Crashed {
            let reason = ctx.platform.last_error.as_deref().unwrap_or("crashed");
            return Err(Failure::new(
                FailureCode::Crashed,
                format!("the vehicle crashed ({reason}) and must be reset"),
            ));
        }
        if ctx.state.valid.position {
            self.capture_start(ctx);
        }
        Ok(())
    }

    fn run(&mut self, ctx: &BehaviorContext, requests: &mut Vec<PlatformRequest>) -> Step {
        if let Some(step) = self.wait_ready(ctx) {
            return step;
        }
        if let Some(step) = self.arm(ctx, requests) {
            return step;
        }
        // Still on the ground after asking the autopilot's own takeoff: the answer was lost or a
        // refusal (ArduCopter once let NAV_TAKEOFF pass right after arming, then disarmed after
        // its idle delay while Kestrel's velocity setpoints, which it ignores on the ground, went
        // on). Asked again each period while it sits there.
        let on_ground = ctx.platform.armed && ctx.platform.flight == FlightStatus::Landed;
        let asked_s = self
            .takeoff_asked_at
            .map_or(f64::INFINITY, |t| seconds_since(ctx.now, t));
        if ctx.capabilities.native_takeoff
            && on_ground
            && asked_s >= REQUEST_PERIOD.as_secs_f64() * 2.0
        {
            self.ask_takeoff(ctx, requests);
        }
        self.climb_to_height(ctx)
    }
}

impl Takeoff {
    /// Waits for the vehicle to be ready to fly (a position, the autopilot's go, a link), at
    /// most `ready_timeout_s`; then captures where it starts. `Some` while waiting or failed.
    fn wait_ready(&mut self, ctx: &BehaviorContext) -> Option<Step> {
        if let Phase::WaitReady { since } = self.phase {
            let since = since.unwrap_or(ctx.now);
            let ready = ctx.state.valid.position
                && ctx.platform.ready_to_fly
                && ctx.platform.link == LinkHealth::Ok;
            if !ready {
                if seconds_since(ctx.now, since) > ctx.config.ready_timeout_s {
                    let reason = ctx.platform.last_error.clone().unwrap_or_else(|| {
                        if ctx.state.valid.position {
                            "the autopilot reports it cannot arm yet".into()
                        } else {
                            "no position estimate".into()
                        }
                    });
                    return Some(Step::Failed(Failure::new(
                        FailureCode::NotReady,
                        format!(
                            "vehicle not ready to fly after {:.0} s: {reason}",
                            ctx.config.ready_timeout_s
                        ),
                    )));
                }
                self.phase = Phase::WaitReady { since: Some(since) };
                return Some(Step::Running {
                    reference: None,
                    feedback: json!({ "waiting_for": "vehicle ready to fly" }),
                });
            }
            self.capture_start(ctx);
            self.phase = Phase::Arming {
                since: None,
                last_request: None,
            };
        }
        None
    }

    /// Arms and enters offboard (or asks the autopilot's own takeoff), asking again every
    /// [`REQUEST_PERIOD`], at most `arm_timeout_s`. `Some` while arming or failed.
    fn arm(&mut self, ctx: &BehaviorContext, requests: &mut Vec<PlatformRequest>) -> Option<Step> {
        let ground_hold = MotionReference::hold(
            Vec3::new(self.target.x, self.target.y, ctx.position().z),
            self.yaw_rad,
            self.goal.speed,
        );
        if let Phase::Arming {
            since,
            last_request,
        } = self.phase
        {
            let since = since.unwrap_or(ctx.now);
            if ctx.platform.armed && (ctx.platform.offboard || ctx.capabilities.native_takeoff) {
                if ctx.capabilities.native_takeoff {
                    self.ask_takeoff(ctx, requests);
                }
                self.phase = Phase::Climbing;
            } else {
                if seconds_since(ctx.now, since) > ctx.config.arm_timeout_s {
                    let failure = match ctx.platform.last_error.clone() {
                        Some(reason) => Failure::new(FailureCode::AutopilotRefused, reason),
                        None => Failure::new(
                            FailureCode::AutopilotSilent,
                            "no answer from the autopilot",
                        ),
                    };
                    return Some(Step::Failed(
                        failure.within("could not arm and enter offboard"),
                    ));
                }
                if last_request.is_none_or(|t| ctx.now.saturating_sub(t) >= REQUEST_PERIOD) {
                    if !ctx.platform.armed {
                        requests.push(PlatformRequest::Arm);
                    }
                    if !ctx.platform.offboard {
                        requests.push(PlatformRequest::StartOffboard);
                    }
                    self.phase = Phase::Arming {
                        since: Some(since),
                        last_request: Some(ctx.now),
                    };
                } else {
                    self.phase = Phase::Arming {
                        since: Some(since),
                        last_request,
                    };
                }
                // Stream a setpoint where the vehicle sits: PX4 needs one before OFFBOARD.
                return Some(Step::Running {
                    reference: Some(ground_hold),
                    feedback: self.feedback(ctx),
                });
            }
        }
        None
    }

    /// Climbs to the target height (on the autopilot's own takeoff while far below, unless it
    /// stalled) until it holds there; fails on a disarm or without progress.
    fn climb_to_height(&mut self, ctx: &BehaviorContext) -> Step {
        if !ctx.platform.armed {
            return Step::Failed(Failure::new(
                FailureCode::AutopilotRefused,
                ctx.platform
                    .last_error
                    .clone()
                    .unwrap_or_else(|| "disarmed during takeoff".into()),
            ));
        }
        let error = self.target.z - ctx.position().z;
        if error.abs() < ctx.config.takeoff_threshold_m && ctx.state.velocity_enu_mps.z.abs() < 0.1
        {
            return Step::Succeeded;
        }
        let stuck_s = self
            .climb
            .get_or_insert_with(|| Progress::new(ctx.now))
            .update(error.abs(), ctx.config.takeoff_threshold_m, ctx.now);
        let far_below = error > ctx.config.takeoff_threshold_m * 4.0;
        // Held for a lost peer, even near the height: say so rather than wait unexplained.
        let held = super::progress::lost_peer(ctx).is_some();
        if stuck_s > ctx.config.no_progress_timeout_s && (far_below || held) {
            return Step::Failed(super::progress::stuck(
                ctx,
                format!(
                    "no progress for {:.0} s, {error:.2} m below the takeoff height",
                    ctx.config.no_progress_timeout_s
                ),
            ));
        }
        // The autopilot's own climb (NAV_TAKEOFF) may stop short of the height (its own
        // acceptance): Kestrel then finishes the climb on its setpoints instead of waiting.
        // On the ground the autopilot's takeoff is asked again instead (ArduCopter ignores
        // setpoints there).
        self.finishing |= stuck_s > NATIVE_STALL_S && ctx.platform.flight != FlightStatus::Landed;
        let reference = if ctx.capabilities.native_takeoff && far_below && !self.finishing {
            None
        } else {
            Some(MotionReference::hold(
                self.target,
                self.yaw_rad,
                self.goal.speed,
            ))
        };
        Step::Running {
            reference,
            feedback: self.feedback(ctx),
        }
    }
}

impl Takeoff {
    fn ask_takeoff(&mut self, ctx: &BehaviorContext, requests: &mut Vec<PlatformRequest>) {
        requests.push(PlatformRequest::Takeoff {
            height_m: self.goal.height,
        });
        self.takeoff_asked_at = Some(ctx.now);
    }

    fn feedback(&self, ctx: &BehaviorContext) -> serde_json::Value {
        json!({
            "actual_takeoff_height": ctx.position().z - (self.target.z - self.goal.height),
            "actual_takeoff_speed": ctx.state.velocity_enu_mps.z,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::behavior::testing::Scene;

    fn on_the_ground() -> Scene {
        let mut scene = Scene::flying();
        scene.platform.armed = false;
        scene.platform.offboard = false;
        scene.platform.flight = FlightStatus::Disarmed;
        scene
    }

    fn run(t: &mut Takeoff, scene: &Scene, now: Duration) -> (Step, Vec<PlatformRequest>) {
        let mut requests = Vec::new();
        let step = t.run(&scene.ctx_at(now), &mut requests);
        (step, requests)
    }

    #[test]
    fn asks_to_arm_once_a_second_and_fails_with_the_autopilot_reason() {
        let mut scene = on_the_ground();
        let mut takeoff = Takeoff::new(TakeoffGoal {
            height: 2.0,
            speed: 1.0,
        });
        takeoff.activate(&scene.ctx(0)).unwrap();
        let ms = Duration::from_millis;
        let (step, requests) = run(&mut takeoff, &scene, ms(0));
        assert_eq!(
            requests,
            [PlatformRequest::Arm, PlatformRequest::StartOffboard]
        );
        assert!(
            matches!(
                step,
                Step::Running {
                    reference: Some(_),
                    ..
                }
            ),
            "streams a setpoint before offboard"
        );
        assert!(run(&mut takeoff, &scene, ms(500)).1.is_empty());
        assert_eq!(run(&mut takeoff, &scene, ms(1000)).1.len(), 2);
        scene.platform.last_error = Some("arming denied: battery empty".into());
        let (step, _) = run(&mut takeoff, &scene, ms(15_100));
        assert_eq!(
            step,
            Step::Failed(Failure::new(
                FailureCode::AutopilotRefused,
                "could not arm and enter offboard: arming denied: battery empty"
            ))
        );
    }

    #[test]
    fn climbs_to_the_height_above_the_takeoff_point() {
        let mut scene = on_the_ground();
        scene.set_position(Vec3::new(3.0, 4.0, 0.5), Vec3::zeros());
        let mut takeoff = Takeoff::new(TakeoffGoal {
            height: 2.0,
            speed: 1.0,
        });
        takeoff.activate(&scene.ctx(0)).unwrap();
        scene.platform.armed = true;
        scene.platform.offboard = true;
        let (step, requests) = run(&mut takeoff, &scene, Duration::from_secs(1));
        assert!(requests.is_empty());
        match step {
            Step::Running {
                reference:
                    Some(MotionReference::Position {
                        position_enu_m,
                        max_speed_mps,
                        ..
                    }),
                ..
            } => {
                assert_eq!(position_enu_m, Vec3::new(3.0, 4.0, 2.5));
                assert_eq!(max_speed_mps, 1.0);
            }
            other => panic!("{other:?}"),
        }
        scene.set_position(Vec3::new(3.0, 4.0, 2.48), Vec3::new(0.0, 0.0, 0.05));
        assert_eq!(
            run(&mut takeoff, &scene, Duration::from_secs(4)).0,
            Step::Succeeded
        );
    }

    /// On the ground with an autopilot that takes off by itself (NAV_TAKEOFF), a 5 m takeoff
    /// activated.
    fn native_takeoff() -> (Scene, Takeoff) {
        let mut scene = on_the_ground();
        scene.capabilities.native_takeoff = true;
        let mut takeoff = Takeoff::new(TakeoffGoal {
            height: 5.0,
            speed: 1.0,
        });
        takeoff.activate(&scene.ctx(0)).unwrap();
        (scene, takeoff)
    }

    #[test]
    fn native_takeoff_is_requested_after_arming() {
        let (mut scene, mut takeoff) = native_takeoff();
        let (_, requests) = run(&mut takeoff, &scene, Duration::ZERO);
        assert_eq!(
            requests,
            [PlatformRequest::Arm, PlatformRequest::StartOffboard]
        );
        scene.platform.armed = true;
        let (step, requests) = run(&mut takeoff, &scene, Duration::from_secs(1));
        assert_eq!(requests, [PlatformRequest::Takeoff { height_m: 5.0 }]);
        assert!(
            matches!(
                step,
                Step::Running {
                    reference: None,
                    ..
                }
            ),
            "the autopilot climbs by itself"
        );
    }

    #[test]
    fn native_takeoff_is_asked_again_while_the_vehicle_sits_on_the_ground() {
        let (mut scene, mut takeoff) = native_takeoff();
        run(&mut takeoff, &scene, Duration::ZERO);
        scene.platform.armed = true;
        scene.platform.flight = FlightStatus::Landed;
        let s = Duration::from_secs;
        let asks = |from: u64, to: u64, takeoff: &mut Takeoff, scene: &Scene| {
            let mut n = 0;
            for t in from..to {
                let (step, requests) = run(takeoff, scene, s(t));
                let on_ground = scene.platform.flight == FlightStatus::Landed;
                assert!(
                    !on_ground
                        || matches!(
                            step,
                            Step::Running {
                                reference: None,
                                ..
                            }
                        ),
                    "{step:?}"
                );
                n += requests
                    .iter()
                    .filter(|r| matches!(r, PlatformRequest::Takeoff { .. }))
                    .count();
            }
            n
        };
        // Asked on arming, then every 2 s while it sits there; the climb is left to the
        // autopilot (no setpoints, which ArduCopter ignores on the ground).
        assert_eq!(asks(1, 8, &mut takeoff, &scene), 4);
        // Off the ground: not asked again.
        scene.platform.flight = FlightStatus::TakingOff;
        assert_eq!(asks(8, 10, &mut takeoff, &scene), 0);
    }

    #[test]
    fn waits_for_a_position_estimate_then_fails_with_the_autopilot_reason() {
        let mut scene = on_the_ground();
        scene.state.valid = crate::types::Validity::default();
        scene.platform.ready_to_fly = false;
        scene.platform.last_error = Some("Arm: Need Position Estimate".into());
        let mut takeoff = Takeoff::new(TakeoffGoal {
            height: 2.0,
            speed: 1.0,
        });
        takeoff.activate(&scene.ctx(0)).unwrap();
        let s = Duration::from_secs;
        let (step, requests) = run(&mut takeoff, &scene, s(0));
        assert!(
            requests.is_empty(),
            "nothing is commanded before the vehicle is ready"
        );
        assert!(
            matches!(
                step,
                Step::Running {
                    reference: None,
                    ..
                }
            ),
            "{step:?}"
        );
        let (step, _) = run(&mut takeoff, &scene, s(59));
        assert!(
            matches!(step, Step::Running { .. }),
            "still waiting within the timeout"
        );
        let (step, _) = run(&mut takeoff, &scene, s(61));
        match step {
            Step::Failed(reason) => {
                assert!(
                    reason.message.contains("Arm: Need Position Estimate"),
                    "{reason}"
                )
            }
            other => panic!("expected a failure, got {other:?}"),
        }
    }

    #[test]
    fn starts_arming_once_the_vehicle_becomes_ready() {
        let mut scene = on_the_ground();
        scene.state.valid = crate::types::Validity::default();
        scene.platform.ready_to_fly = false;
        let mut takeoff = Takeoff::new(TakeoffGoal {
            height: 2.0,
            speed: 1.0,
        });
        takeoff.activate(&scene.ctx(0)).unwrap();
        let s = Duration::from_secs;
        run(&mut takeoff, &scene, s(0));
        scene.state.valid = crate::types::Validity::ALL;
        scene.platform.ready_to_fly = true;
        let (_, requests) = run(&mut takeoff, &scene, s(40));
        assert!(requests.contains(&PlatformRequest::Arm), "{requests:?}");
    }

    #[test]
    fn an_autopilot_climb_that_stops_short_is_finished_on_setpoints() {
        let mut scene = Scene::flying();
        scene.capabilities.native_takeoff = true;
        let mut t = Takeoff::new(TakeoffGoal {
            height: 3.0,
            speed: 1.0,
        });
        t.capture_start(&scene.ctx(0));
        t.phase = Phase::Climbing;
        // NAV_TAKEOFF climbing: the autopilot flies, Kestrel sends nothing.
        scene.set_position(Vec3::new(0.0, 0.0, 1.0), Vec3::new(0.0, 0.0, 1.0));
        assert!(matches!(
            run(&mut t, &scene, Duration::from_secs(1)).0,
            Step::Running {
                reference: None,
                ..
            }
        ));
        // Stopped at 2.69 m of 3: after a few seconds Kestrel climbs the rest itself.
        scene.set_position(Vec3::new(0.0, 0.0, 2.69), Vec3::zeros());
        assert!(matches!(
            run(&mut t, &scene, Duration::from_secs(3)).0,
            Step::Running {
                reference: None,
                ..
            }
        ));
        match run(&mut t, &scene, Duration::from_secs(7)).0 {
            Step::Running {
                reference: Some(MotionReference::Position { position_enu_m, .. }),
                ..
            } => assert!((position_enu_m.z - 3.0).abs() < 1e-9),
            other => panic!("{other:?}"),
        }
        // Still not climbing at all: no_progress, never a wait for ever.
        assert!(matches!(
            run(&mut t, &scene, Duration::from_secs(30)).0,
            Step::Failed(f) if f.code == FailureCode::NoProgress
        ));
    }
}
