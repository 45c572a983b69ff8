//! Behaviors: goal-driven skills (takeoff, go_to, follow_path ...) with one lifecycle.
//!
//! In: goals (JSON arguments, parsed and checked by each behavior) and, each tick, a
//! [`BehaviorContext`] with the estimated state, platform status and frames.
//! Out: each tick, a motion reference for the controller, platform requests, and events
//! (started, paused, resumed, modified, finished with a result).
//!
//! Lifecycle, shared by all: `start(goal)` → running; `pause` → paused (the server holds the
//! vehicle where it is); `resume` → running again from where it is; `modify(goal)` changes the
//! goal in flight; `stop` → aborted. Results: succeeded, failed(reason), aborted(reason).

mod arrival;
mod explore;
mod failure;
pub mod fleet;
mod follow_path;
mod follow_reference;
mod go_to;
mod goal;
mod hover;
mod land;
mod nav_path;
mod navigate_to;
pub mod payload;
mod progress;
mod registry;
mod rotate;
mod sequence;
mod server;
pub mod services;
mod takeoff;
#[cfg(test)]
pub(crate) mod testing;

pub use failure::{Failure, FailureCode};
pub use goal::{check_non_negative, FramedPoint, GoalError, YawMode, WGS84};
pub use registry::{BehaviorSpec, Goal, GoalSummary, ParsedGoal, Registry, Resource};
pub use server::{
    ActiveInfo, BehaviorEvent, BehaviorId, BehaviorResult, BehaviorServer, RunState, ServerError,
};

use crate::control::{MotionReference, YawTarget};
use crate::estimator::frames::FrameTree;
use crate::estimator::geodetic::GeodeticOrigin;
use crate::mapping::server::MapServer;
use crate::types::{Capabilities, PlatformRequest};
use crate::types::{EstimatedState, PlatformStatus, Vec3};
use serde::{Deserialize, Serialize};
use std::time::Duration;

/// Vehicle-wide tuning the behaviors share (SI units).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct BehaviorConfig {
    /// go_to and follow_reference finish within this 3-D distance of the goal (m).
    pub goal_threshold_m: f64,
    /// follow_path counts a waypoint passed within this distance (m).
    pub waypoint_threshold_m: f64,
    /// takeoff finishes within this distance of the requested height (m).
    pub takeoff_threshold_m: f64,
    /// Acceleration used to plan trajectories (m/s^2).
    pub max_acceleration_mps2: f64,
    /// A behavior that gets no closer to its goal for this long fails (s); within 0.5 m of the
    /// point a go_to or a path flies to, where an autopilot's own hold wanders, a second counts
    /// a third.
    pub no_progress_timeout_s: f64,
    /// Arming and entering offboard must complete within this time (s).
    pub arm_timeout_s: f64,
    /// A takeoff started before the vehicle is ready to fly (no position estimate yet, e.g.
    /// ArduPilot's EKF about 40 s after boot) waits this long before failing (s).
    pub ready_timeout_s: f64,
    /// Speed used to hold position after pause or stop (m/s).
    pub hold_speed_mps: f64,
}

impl Default for BehaviorConfig {
    fn default() -> Self {
        Self {
            goal_threshold_m: 0.1,
            waypoint_threshold_m: 0.2,
            takeoff_threshold_m: 0.05,
            max_acceleration_mps2: 2.0,
            no_progress_timeout_s: 20.0,
            arm_timeout_s: 15.0,
            ready_timeout_s: 60.0,
            hold_speed_mps: 1.0,
        }
    }
}

/// What a behavior sees each tick.
pub struct BehaviorContext<'a> {
    /// This drone's id (as in the fleet view).
    pub drone_id: &'a str,
    pub now: Duration,
    pub dt_s: f64,
    pub state: &'a EstimatedState,
    pub platform: &'a PlatformStatus,
    pub capabilities: Capabilities,
    pub frames: &'a FrameTree,
    pub geo_origin: &'a GeodeticOrigin,
    /// Where the vehicle last armed, in `earth`; `None` before the first arming.
    pub home_enu_m: Option<Vec3>,
    /// The point the previous motion reference held the vehicle at (a go_to's goal as it
    /// ends, a path's end), `None` after a velocity.
    pub held_at_enu_m: Option<Vec3>,
    pub config: &'a BehaviorConfig,
    /// The exploration's weights (config `[exploration]`), which an `explore` goal's own
    /// `settings` override field by field.
    pub exploration: &'a crate::exploration::online::settings::ExplorationSettings,
    /// The drone's map (`None` when mapping is off), for behaviors that plan.
    pub map: Option<&'a MapServer>,
    /// Outcomes (the autopilot's acks) of platform requests completed since the last tick,
    /// for behaviors that wait for them (gimbal, camera).
    pub request_results: &'a [crate::types::RequestResult],
    /// Slow work (plans) asked on one tick, answered on a later one.
    pub services: &'a services::ServiceDesk,
    /// Every drone's latest state (this one included), as the host saw it before this tick.
    pub fleet: &'a crate::types::FleetView,
    /// How fast the position estimate may drift (m/s; the map correction's `drift_mps`, 0
    /// where nothing drifts): the vehicle flies up to this much faster than it is sent.
    pub estimate_drift_mps: f64,
    /// How the safety stage changed the last setpoint sent (`None`: it passed unchanged), so
    /// a behavior can tell its own drift from a hold it did not ask for.
    pub safety_override: Option<crate::safety::OverrideKind>,
    /// How far the map correction moved this drone's estimate this tick (ENU m, horizontal;
    /// zero without a step): the vehicle did not move, its place on the map did.
    pub map_step_m: Vec3,
}

impl BehaviorContext<'_> {
    pub fn position(&self) -> Vec3 {
        self.state.pose.position_m
    }
    pub fn yaw(&self) -> f64 {
        self.state.pose.yaw_rad()
    }
    /// The speed to plan a path with for a goal's `speed_mps`: what the vehicle can be sent
    /// without flying faster than the goal says (its profile's overshoot, its estimate's drift;
    /// the controller caps every command the same way).
    pub fn planned_speed_mps(&self, speed_mps: f64) -> f64 {
        crate::control::commanded_horizontal_speed(
            speed_mps,
            crate::control::commanded_speed_share(self.capabilities.velocity_overshoot),
            self.estimate_drift_mps,
        )
    }
    /// A reference that holds the current position and heading.
    pub fn hold_here(&self) -> MotionReference {
        MotionReference::hold(self.position(), self.yaw(), self.config.hold_speed_mps)
    }
    /// After an item succeeded: hold the point it took the vehicle to (its goal, which a
    /// vehicle arriving at speed overshoots by some decimetres on PX4) when near it, else here.
    pub fn hold_reached(&self) -> MotionReference {
        match self.held_at_enu_m {
            Some(p) if (p - self.position()).norm() <= REACHED_POINT_REACH_M => {
                MotionReference::hold(p, self.yaw(), self.config.hold_speed_mps)
            }
            _ => self.hold_here(),
        }
    }
    pub fn is_flying(&self) -> bool {
        self.platform.flight.is_airborne() && self.platform.armed
    }
}

/// How near the vehicle the point an item held must be to be held after it (m).
pub const REACHED_POINT_REACH_M: f64 = 0.5;

/// Result of one behavior tick.
#[derive(Debug, Clone, PartialEq)]
pub enum Step {
    /// Still working. `reference` = what the controller should track (None: nothing to send,
    /// e.g. during an autopilot-native takeoff); `feedback` is published as is.
    Running {
        reference: Option<MotionReference>,
        feedback: serde_json::Value,
    },
    Succeeded,
    Failed(Failure),
}

/// One behavior instance, created from a goal by its [`BehaviorSpec`].
///
/// Contract: `activate` is called once before any `run`; it rejects (Err with a reason) goals
/// that cannot be flown now, and must not command anything itself. `run` is called every tick
/// while running (never while paused). `modify` replaces the goal in flight; the default
/// refuses. `resume` is called after a pause, before the next `run`.
pub trait Behavior: Send {
    fn activate(&mut self, ctx: &BehaviorContext) -> Result<(), Failure>;
    fn run(&mut self, ctx: &BehaviorContext, requests: &mut Vec<PlatformRequest>) -> Step;
    fn modify(&mut self, _ctx: &BehaviorContext, _goal: &ParsedGoal) -> Result<(), Failure> {
        Err(Failure::invalid(
            "this behavior cannot be modified in flight",
        ))
    }
    fn resume(&mut self, _ctx: &BehaviorContext) {}
    /// Where the behavior is taking the vehicle (`earth` ENU m), for the fleet view; `None`
    /// when it has no single goal point.
    fn goal_enu_m(&self) -> Option<Vec3> {
        None
    }
}

/// Heading error (rad) below which a behavior with a heading goal counts it as reached.
pub(crate) const YAW_THRESHOLD_RAD: f64 = 0.03;

/// Whether the heading asked by `mode` is reached; modes without a heading at the goal
/// (path facing, or a face point right above the vehicle) always are. A goal is only done when
/// its heading is, because the hold that follows keeps the heading the vehicle has then.
pub(crate) fn heading_reached(mode: &goal::ResolvedYaw, ctx: &BehaviorContext) -> bool {
    let wanted = match mode {
        goal::ResolvedYaw::PathFacing => return true,
        goal::ResolvedYaw::Fixed(angle) => *angle,
        goal::ResolvedYaw::Face(point) => {
            let d = point - ctx.position();
            if d.xy().norm() < 0.3 {
                return true;
            }
            d.y.atan2(d.x)
        }
    };
    crate::types::wrap_angle_rad(wanted - ctx.yaw()).abs() < YAW_THRESHOLD_RAD
}

/// Horizontal distance from its goal within which a path-facing vehicle keeps its heading
/// (m): nearer, the direction to the goal swings with every centimetre of position error.
pub(crate) const PATH_FACING_HOLD_M: f64 = 1.0;

/// A path-facing heading: along the direction of travel while there is a clear one, else the
/// heading it last faced (the vehicle's own at first), so it never flips near a goal.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct PathHeading {
    held_rad: Option<f64>,
}

impl PathHeading {
    /// The heading along `direction` (ENU; its horizontal part), or the one held.
    pub(crate) fn facing(&mut self, direction: Option<Vec3>, ctx: &BehaviorContext) -> f64 {
        match direction.filter(|d| d.xy().norm() > 1e-6) {
            Some(d) => *self.held_rad.insert(d.y.atan2(d.x)),
            None => *self.held_rad.get_or_insert_with(|| ctx.yaw()),
        }
    }

    /// The direction to `goal`, or `None` within [`PATH_FACING_HOLD_M`] of it.
    pub(crate) fn toward(goal: &Vec3, ctx: &BehaviorContext) -> Option<Vec3> {
        let d = goal - ctx.position();
        (d.xy().norm() > PATH_FACING_HOLD_M).then_some(d)
    }
}

/// Turns a yaw mode into a yaw target for this tick; `direction` is the way the vehicle goes
/// (`None` when it has no clear one, as near its goal).
pub(crate) fn yaw_target(
    mode: &goal::ResolvedYaw,
    ctx: &BehaviorContext,
    path: &mut PathHeading,
    direction: Option<Vec3>,
) -> YawTarget {
    match mode {
        goal::ResolvedYaw::Fixed(angle) => YawTarget::Angle(*angle),
        goal::ResolvedYaw::PathFacing => YawTarget::Angle(path.facing(direction, ctx)),
        goal::ResolvedYaw::Face(point) => {
            let d = point - ctx.position();
            // Too close to tell a direction: keep the heading rather than spin.
            YawTarget::Angle(if d.xy().norm() < 0.3 {
                ctx.yaw()
            } else {
                d.y.atan2(d.x)
            })
        }
    }
}
