//! `land`: descend at `speed` until touchdown, then disarm.
//!
//! With `native_land` the autopilot lands (its land mode) and disarms, once the vehicle has
//! stopped over the landing point (at most [`SETTLE_BUDGET_S`]): a land mode lands where the
//! vehicle is when told, and one told while it still moves lands off the point by its velocity
//! times the autopilot's lag. Otherwise Kestrel flies
//! the descent, holding the point where the landing began against the autopilot's own drift,
//! tells the platform every tick ([`PlatformRequest::LandOnSetpoints`]), and keeps pushing down
//! until disarmed. Touchdown is the platform's landed state, or (for platforms without a land
//! detector) no descent for one second after at least 0.2 m of descent.

use super::arrival::Arrival;
use super::goal::{check_positive, GoalError};
use super::registry::{BehaviorSpec, Goal, Resource};
use super::server::seconds_since;
use super::{Behavior, BehaviorContext, Failure, FailureCode, Step};
use crate::control::{MotionReference, YawTarget};
use crate::types::PlatformRequest;
use crate::types::{FlightStatus, Vec3};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};
use serde_json::json;
use std::time::Duration;

#[derive(Debug, Clone, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct LandGoal {
    /// Descent speed (m/s).
    #[serde(default = "default_speed")]
    pub speed: f64,
}

fn default_speed() -> f64 {
    0.5
}

impl Goal for LandGoal {
    fn check(&self) -> Result<(), GoalError> {
        check_positive("speed", self.speed, "m/s")
    }
    fn speeds_mps(&self) -> Vec<f64> {
        vec![self.speed]
    }
}

pub fn spec() -> BehaviorSpec {
    BehaviorSpec::new(
        "land",
        "Descend until touchdown, then disarm",
        Resource::Motion,
        Land::new,
    )
}

pub struct Land {
    goal: LandGoal,
    hold_xy: Vec3,
    yaw_rad: f64,
    start_z: f64,
    still_since: Option<Duration>,
    touchdown_at: Option<Duration>,
    requested_native: bool,
    /// Whether the vehicle has stopped over the point, before an autopilot's land mode.
    settled: Arrival,
    activated_at: Duration,
    /// Time the descent has waited over its point so far (s).
    gated_s: f64,
    /// The last descent was slowed to wait for the vehicle: stillness is not touchdown.
    waiting_over_point: bool,
    /// The height the descent has come down to (m): it goes down at the descent's speed and
    /// holds while the descent waits, never more than [`DESCENT_LEAD_M`] from the vehicle.
    descent_z: Option<f64>,
}

/// Disarming must be confirmed within this time after touchdown.
const DISARM_TIMEOUT_S: f64 = 5.0;
/// Height above home (m) below which the descent waits for the vehicle to be over its point.
const GATE_HEIGHT_M: f64 = 1.0;
/// Off the point by at most this (m): full descent speed; by [`GATE_STOP_M`]: none.
const GATE_FULL_M: f64 = 0.04;
const GATE_STOP_M: f64 = 0.12;
/// The descent waits at most this long in all (s): a vehicle that cannot hold its point still
/// lands (the battery does not wait).
const GATE_BUDGET_S: f64 = 20.0;
/// Before an autopilot's land mode: the vehicle stops within this of the point (m) ...
const SETTLE_REACH_M: f64 = 0.1;
/// ... for at most this long (s), then lands where it is.
const SETTLE_BUDGET_S: f64 = 5.0;
/// How far the descent's height may run ahead of (or behind) the vehicle (m).
const DESCENT_LEAD_M: f64 = 0.25;

impl Land {
    pub(crate) fn new(goal: LandGoal) -> Self {
        Self {
            goal,
            hold_xy: Vec3::zeros(),
            yaw_rad: 0.0,
            start_z: 0.0,
            still_since: None,
            touchdown_at: None,
            requested_native: false,
            settled: Arrival::before_landing(),
            activated_at: Duration::ZERO,
            gated_s: 0.0,
            waiting_over_point: false,
            descent_z: None,
        }
    }
}

impl Behavior for Land {
    fn activate(&mut self, ctx: &BehaviorContext) -> Result<(), Failure> {
        if !ctx.platform.armed {
            return Err(Failure::new(
                FailureCode::NotFlying,
                "not armed: already on the ground",
            ));
        }
        self.hold_xy = landing_point(ctx);
        self.yaw_rad = ctx.yaw();
        self.start_z = ctx.position().z;
        self.activated_at = ctx.now;
        Ok(())
    }

    fn resume(&mut self, ctx: &BehaviorContext) {
        self.hold_xy = ctx.position();
        self.activated_at = ctx.now;
        self.settled.reset();
        self.still_since = None;
        self.descent_z = None;
    }

    fn run(&mut self, ctx: &BehaviorContext, requests: &mut Vec<PlatformRequest>) -> Step {
        let feedback = json!({
            "actual_land_height": ctx.position().z,
            "actual_land_speed": ctx.state.velocity_enu_mps.z,
        });
        if !ctx.capabilities.native_land && ctx.platform.armed {
            requests.push(PlatformRequest::LandOnSetpoints);
        }
        if let Some(t) = self.touchdown_at {
            if !ctx.platform.armed {
                return Step::Succeeded;
            }
            if seconds_since(ctx.now, t) > DISARM_TIMEOUT_S {
                return Step::Failed(Failure::new(
                    FailureCode::AutopilotRefused,
                    format!(
                        "landed but disarm refused: {}",
                        ctx.platform.last_error.clone().unwrap_or_default()
                    ),
                ));
            }
            requests.push(PlatformRequest::Disarm);
            // On the ground, still pushing down until disarmed: the setpoints go on (PX4 leaves
            // OFFBOARD for its failsafe when they stop) and hold the vehicle on the ground.
            return Step::Running {
                reference: Some(self.descent(ctx)),
                feedback,
            };
        }
        if !ctx.platform.armed {
            // The autopilot disarmed by itself after its own touchdown detection.
            return Step::Succeeded;
        }
        if ctx.capabilities.native_land {
            if !self.requested_native {
                if !self.settled_over_point(ctx) {
                    return Step::Running {
                        reference: Some(MotionReference::hold(
                            Vec3::new(self.hold_xy.x, self.hold_xy.y, self.start_z),
                            self.yaw_rad,
                            ctx.config.hold_speed_mps,
                        )),
                        feedback,
                    };
                }
                requests.push(PlatformRequest::Land);
                self.requested_native = true;
            }
            return Step::Running {
                reference: None,
                feedback,
            };
        }
        if self.touched_down(ctx) {
            self.touchdown_at = Some(ctx.now);
            requests.push(PlatformRequest::Disarm);
        }
        Step::Running {
            reference: Some(self.descent(ctx)),
            feedback,
        }
    }
}

/// Where to land: under the point the previous item held the vehicle at (a go_to's goal, a
/// path's end), when the vehicle is still near it (a vehicle arriving at speed overshoots it by
/// its velocity times the autopilot's lag, some decimetres on PX4); else where it is.
fn landing_point(ctx: &BehaviorContext) -> Vec3 {
    let here = ctx.position();
    match ctx.held_at_enu_m {
        Some(p) if (p.xy() - here.xy()).norm() <= super::REACHED_POINT_REACH_M => {
            Vec3::new(p.x, p.y, here.z)
        }
        _ => here,
    }
}

impl Land {
    /// Straight down at `speed` over the landing point: the position hold pulls the vehicle
    /// back over it (against the autopilot's own drift or an overshoot of the item before)
    /// while the feed-forward descends. (A hold target far below would pull sideways only at
    /// the slope of the line to it, a few cm/s; a trajectory reference's unbounded integral
    /// wound up against the 0.5 m/s cap and swung 1.5 m on real PX4 SIH.)
    ///
    /// Within [`GATE_HEIGHT_M`] of the ground the descent slows while the vehicle is off the
    /// point, and stops [`GATE_STOP_M`] off it, until back over it ([`GATE_BUDGET_S`] at most),
    /// so a drifting autopilot touches down where it was told to. The height is held too while
    /// it waits (a hold at the vehicle's own height let the autopilot's vertical drift set it
    /// down off the point, 0.4-0.8 m on the wandering fake PX4).
    fn descent(&mut self, ctx: &BehaviorContext) -> MotionReference {
        let off_m = (ctx.position().xy() - self.hold_xy.xy()).norm();
        let low = ctx
            .home_enu_m
            .is_none_or(|home| ctx.position().z - home.z < GATE_HEIGHT_M);
        let mut speed = self.goal.speed;
        if low && self.gated_s < GATE_BUDGET_S {
            let share = ((GATE_STOP_M - off_m) / (GATE_STOP_M - GATE_FULL_M)).clamp(0.0, 1.0);
            if share < 1.0 {
                self.gated_s += ctx.dt_s;
            }
            speed *= share;
        }
        self.waiting_over_point = speed < self.goal.speed;
        let z = ctx.position().z;
        let descent_z = (self.descent_z.unwrap_or(z) - speed * ctx.dt_s)
            .clamp(z - DESCENT_LEAD_M, z + DESCENT_LEAD_M);
        self.descent_z = Some(descent_z);
        MotionReference::Position {
            position_enu_m: Vec3::new(self.hold_xy.x, self.hold_xy.y, descent_z),
            velocity_ff_enu_mps: Vec3::new(0.0, 0.0, -speed),
            yaw: YawTarget::Angle(self.yaw_rad),
            max_speed_mps: self.goal.speed,
        }
    }

    /// Before an autopilot's land mode: stopped over the point, or out of time for it.
    fn settled_over_point(&mut self, ctx: &BehaviorContext) -> bool {
        let off_m = (ctx.position().xy() - self.hold_xy.xy()).norm();
        self.settled.update(off_m <= SETTLE_REACH_M, ctx)
            || seconds_since(ctx.now, self.activated_at) >= SETTLE_BUDGET_S
    }

    fn touched_down(&mut self, ctx: &BehaviorContext) -> bool {
        if ctx.platform.flight == FlightStatus::Landed {
            return true;
        }
        let descended = self.start_z - ctx.position().z > 0.2;
        let still =
            ctx.state.velocity_enu_mps.z.abs() < 0.2 * self.goal.speed && !self.waiting_over_point;
        if descended && still {
            let since = *self.still_since.get_or_insert(ctx.now);
            seconds_since(ctx.now, since) > 1.0
        } else {
            self.still_since = None;
            false
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::behavior::testing::Scene;

    fn run(land: &mut Land, scene: &Scene, t: Duration) -> (Step, Vec<PlatformRequest>) {
        let mut requests = Vec::new();
        let step = land.run(&scene.ctx_at(t), &mut requests);
        (step, requests)
    }

    #[test]
    fn without_a_land_detector_touchdown_is_a_second_without_descent() {
        let mut scene = Scene::flying();
        scene.set_position(Vec3::new(1.0, 2.0, 2.0), Vec3::zeros());
        let mut land = Land::new(LandGoal { speed: 0.5 });
        land.activate(&scene.ctx(0)).unwrap();
        let ms = Duration::from_millis;
        // Descending: a reference below, never a disarm; the platform is told every tick.
        scene.set_position(Vec3::new(1.0, 2.0, 1.0), Vec3::new(0.0, 0.0, -0.5));
        let (step, requests) = run(&mut land, &scene, ms(2000));
        assert_eq!(requests, [PlatformRequest::LandOnSetpoints]);
        match step {
            Step::Running {
                reference:
                    Some(MotionReference::Position {
                        position_enu_m,
                        velocity_ff_enu_mps,
                        ..
                    }),
                ..
            } => assert!(velocity_ff_enu_mps.z == -0.5 && position_enu_m.x == 1.0),
            other => panic!("{other:?}"),
        }
        // On the ground (the platform still says flying): still for a second, then disarm.
        scene.set_position(Vec3::new(1.0, 2.0, 0.0), Vec3::zeros());
        let hint = [PlatformRequest::LandOnSetpoints];
        assert_eq!(run(&mut land, &scene, ms(4000)).1, hint);
        assert_eq!(run(&mut land, &scene, ms(4500)).1, hint);
        let (step, requests) = run(&mut land, &scene, ms(5100));
        assert_eq!(
            requests,
            [PlatformRequest::LandOnSetpoints, PlatformRequest::Disarm]
        );
        // Still pushing down over the same point until disarmed: the setpoints never stop.
        match step {
            Step::Running {
                reference:
                    Some(MotionReference::Position {
                        position_enu_m,
                        velocity_ff_enu_mps,
                        ..
                    }),
                ..
            } => assert!(velocity_ff_enu_mps.z == -0.5 && position_enu_m.x == 1.0),
            other => panic!("{other:?}"),
        }
        scene.platform.armed = false;
        assert_eq!(run(&mut land, &scene, ms(5200)).0, Step::Succeeded);
    }

    #[test]
    fn a_refused_disarm_fails_with_the_autopilot_reason() {
        let mut scene = Scene::flying();
        scene.set_position(Vec3::new(0.0, 0.0, 1.0), Vec3::zeros());
        let mut land = Land::new(LandGoal { speed: 0.5 });
        land.activate(&scene.ctx(0)).unwrap();
        scene.set_position(Vec3::zeros(), Vec3::zeros());
        scene.platform.flight = FlightStatus::Landed;
        scene.platform.last_error = Some("disarm refused: vehicle in air".into());
        let (_, requests) = run(&mut land, &scene, Duration::from_secs(3));
        assert_eq!(
            requests,
            [PlatformRequest::LandOnSetpoints, PlatformRequest::Disarm]
        );
        let (step, _) = run(&mut land, &scene, Duration::from_secs(9));
        assert_eq!(
            step,
            Step::Failed(Failure::new(
                FailureCode::AutopilotRefused,
                "landed but disarm refused: disarm refused: vehicle in air"
            ))
        );
    }

    #[test]
    fn the_descent_holds_its_height_while_it_waits_and_leads_the_vehicle_down_otherwise() {
        let mut scene = Scene::flying();
        scene.dt_s = 0.1;
        scene.set_position(Vec3::new(1.0, 2.0, 3.0), Vec3::zeros());
        let mut land = Land::new(LandGoal { speed: 0.5 });
        land.activate(&scene.ctx(0)).unwrap();
        let point = |step: Step| match step {
            Step::Running {
                reference: Some(MotionReference::Position { position_enu_m, .. }),
                ..
            } => position_enu_m,
            other => panic!("{other:?}"),
        };
        let ms = Duration::from_millis;
        // High up: the height comes down 0.05 m a tick (0.5 m/s), at most 0.25 m ahead.
        let z1 = point(run(&mut land, &scene, ms(100)).0).z;
        let z2 = point(run(&mut land, &scene, ms(200)).0).z;
        assert!(
            (z1 - 2.95).abs() < 1e-9 && (z2 - 2.9).abs() < 1e-9,
            "{z1} {z2}"
        );
        for t in (300..2000).step_by(100) {
            run(&mut land, &scene, ms(t));
        }
        let lead = point(run(&mut land, &scene, ms(2000)).0).z;
        assert!((lead - 2.75).abs() < 1e-9, "{lead}");
        // Low and off the point: the height where the wait began holds, though the vehicle
        // sinks under it (the autopilot's own drift), so it is not set down off the point.
        scene.set_position(Vec3::new(1.0, 2.0, 0.5), Vec3::zeros());
        let mut land = Land::new(LandGoal { speed: 0.5 });
        land.activate(&scene.ctx(0)).unwrap();
        scene.set_position(Vec3::new(1.3, 2.0, 0.5), Vec3::zeros());
        let waiting_at = point(run(&mut land, &scene, ms(100)).0).z;
        assert!((waiting_at - 0.5).abs() < 1e-9, "{waiting_at}");
        scene.set_position(Vec3::new(1.3, 2.0, 0.4), Vec3::zeros());
        for t in (200..4000).step_by(100) {
            let z = point(run(&mut land, &scene, ms(t)).0).z;
            assert!((z - waiting_at).abs() < 1e-9, "{z} at {t} ms");
        }
    }

    #[test]
    fn near_the_ground_the_descent_waits_until_the_vehicle_is_over_its_point() {
        let mut scene = Scene::flying();
        scene.dt_s = 0.1;
        scene.set_position(Vec3::new(1.0, 2.0, 3.0), Vec3::zeros());
        let mut land = Land::new(LandGoal { speed: 0.5 });
        land.activate(&scene.ctx(0)).unwrap();
        let descent = |step: Step| match step {
            Step::Running {
                reference:
                    Some(MotionReference::Position {
                        position_enu_m,
                        velocity_ff_enu_mps,
                        ..
                    }),
                ..
            } => (position_enu_m, velocity_ff_enu_mps.z),
            other => panic!("{other:?}"),
        };
        let ms = Duration::from_millis;
        // Low and drifted 0.3 m off: no descent, pulled back over the point.
        scene.set_position(Vec3::new(1.3, 2.0, 0.5), Vec3::zeros());
        let (point, vz) = descent(run(&mut land, &scene, ms(1000)).0);
        assert_eq!((point.x, point.y, vz), (1.0, 2.0, 0.0));
        // Still for seconds while waiting: not a touchdown, no disarm.
        for t in (1100..4000).step_by(100) {
            let (_, requests) = run(&mut land, &scene, ms(t));
            assert_eq!(requests, [PlatformRequest::LandOnSetpoints], "at {t} ms");
        }
        // Back over it: full speed down.
        scene.set_position(Vec3::new(1.02, 2.0, 0.5), Vec3::zeros());
        assert_eq!(descent(run(&mut land, &scene, ms(4100)).0).1, -0.5);
        // Half-way off: half speed.
        scene.set_position(Vec3::new(1.08, 2.0, 0.5), Vec3::zeros());
        let vz = descent(run(&mut land, &scene, ms(4200)).0).1;
        assert!((vz + 0.25).abs() < 1e-9, "{vz}");
        // A vehicle that cannot hold its point still lands: the wait is bounded.
        scene.set_position(Vec3::new(1.3, 2.0, 0.5), Vec3::zeros());
        let mut t = 4300;
        while descent(run(&mut land, &scene, ms(t)).0).1 == 0.0 {
            t += 100;
            assert!(t < 60_000, "waited for ever");
        }
        assert!(t > 20_000, "gave up waiting after {t} ms");
    }

    #[test]
    fn it_lands_under_the_point_the_previous_item_held_when_near_it() {
        let mut scene = Scene::flying();
        scene.set_position(Vec3::new(1.3, 2.0, 3.0), Vec3::new(0.7, 0.0, 0.0));
        scene.held_at_enu_m = Some(Vec3::new(1.0, 2.0, 3.0));
        let mut land = Land::new(LandGoal { speed: 0.5 });
        land.activate(&scene.ctx(0)).unwrap();
        assert_eq!(land.hold_xy.xy(), Vec3::new(1.0, 2.0, 0.0).xy());
        // Far from it (an item stopped half-way): where the vehicle is.
        scene.held_at_enu_m = Some(Vec3::new(5.0, 2.0, 3.0));
        let mut land = Land::new(LandGoal { speed: 0.5 });
        land.activate(&scene.ctx(0)).unwrap();
        assert_eq!(land.hold_xy.xy(), Vec3::new(1.3, 2.0, 0.0).xy());
    }

    #[test]
    fn native_land_asks_the_autopilot_once() {
        let mut scene = Scene::flying();
        scene.capabilities.native_land = true;
        scene.set_position(Vec3::new(0.0, 0.0, 3.0), Vec3::zeros());
        let mut land = Land::new(LandGoal { speed: 0.5 });
        land.activate(&scene.ctx(0)).unwrap();
        let (step, requests) = run(&mut land, &scene, Duration::from_secs(1));
        assert_eq!(requests, [PlatformRequest::Land]);
        assert!(matches!(
            step,
            Step::Running {
                reference: None,
                ..
            }
        ));
        assert!(run(&mut land, &scene, Duration::from_secs(2)).1.is_empty());
        scene.platform.armed = false;
        assert_eq!(
            run(&mut land, &scene, Duration::from_secs(3)).0,
            Step::Succeeded
        );
    }

    #[test]
    fn native_land_waits_for_a_moving_vehicle_to_stop_over_the_point() {
        let mut scene = Scene::flying();
        scene.capabilities.native_land = true;
        scene.set_position(Vec3::new(0.0, 0.0, 3.0), Vec3::new(0.6, 0.0, 0.0));
        let mut land = Land::new(LandGoal { speed: 0.5 });
        land.activate(&scene.ctx(0)).unwrap();
        let ms = Duration::from_millis;
        // Carried on 0.3 m by its speed: held over the point at its height, no land yet.
        scene.set_position(Vec3::new(0.3, 0.0, 3.0), Vec3::new(0.3, 0.0, 0.0));
        let (step, requests) = run(&mut land, &scene, ms(500));
        assert!(requests.is_empty());
        match step {
            Step::Running {
                reference: Some(MotionReference::Position { position_enu_m, .. }),
                ..
            } => assert_eq!(position_enu_m, Vec3::new(0.0, 0.0, 3.0)),
            other => panic!("{other:?}"),
        }
        // Back over it and slow: the autopilot lands.
        scene.set_position(Vec3::new(0.05, 0.0, 3.0), Vec3::new(-0.1, 0.0, 0.0));
        assert_eq!(run(&mut land, &scene, ms(2000)).1, [PlatformRequest::Land]);
    }

    #[test]
    fn native_land_lands_where_it_is_when_the_vehicle_cannot_stop_over_the_point() {
        let mut scene = Scene::flying();
        scene.capabilities.native_land = true;
        scene.set_position(Vec3::new(0.0, 0.0, 3.0), Vec3::zeros());
        let mut land = Land::new(LandGoal { speed: 0.5 });
        land.activate(&scene.ctx(0)).unwrap();
        scene.set_position(Vec3::new(0.4, 0.0, 3.0), Vec3::new(0.5, 0.0, 0.0));
        for t in (100..5000).step_by(100) {
            assert!(run(&mut land, &scene, Duration::from_millis(t))
                .1
                .is_empty());
        }
        let (_, requests) = run(&mut land, &scene, Duration::from_millis(5000));
        assert_eq!(requests, [PlatformRequest::Land]);
    }
}
