//! `navigate_to`: plan a path on the drone's map to a goal in any frame and fly it through
//! `follow_path`, replanning when new map data blocks the path ahead (Aerostack2's
//! `path_planner` behavior, `NavigateToPoint`).
//!
//! In: the goal (point, speed, yaw, planner, safety distance, unknown-cell policy, optional spin)
//! and each tick the context with the drone's map. Out: the `follow_path` child's reference
//! (yaw replaced by a turn rate when spinning) and feedback `distance_remaining`, `replans`,
//! `estimated_time_remaining_s`, `planned_path`, `planning`. Plans happen on activation and
//! when the path ahead is blocked, never every tick, and never on the tick itself: the plan is
//! filed with the context's service desk and the vehicle holds where it is until the answer
//! arrives (the next tick in simulated time). A goal that is plainly unreachable on the current
//! map (outside it, or in or too near a mapped obstacle) is refused at start; no path fails with
//! the planner's reason.

mod goal;

use goal::{NavigateToGoal, UnknownArg};

use super::follow_path::{FollowPath, FollowPathGoal};
use super::goal::YawMode;
use super::goal::{frame_or_earth, InFlight, ResolvedYaw, YawArgs};
use super::nav_path::NavPath;
use super::registry::{BehaviorSpec, Goal, Resource};
use super::server::seconds_since;
use super::services::Ticket;
use super::{Behavior, BehaviorContext, Failure, FailureCode, Step};
use crate::control::{MotionReference, YawTarget};
use crate::estimator::frames::EARTH;
use crate::mapping::server::MapServer;
use crate::planning::{PlanError, PlanRequest, PlannedPath, UnknownPolicy, MAX_UNKNOWN_EXTRA_COST};
use crate::types::PlatformRequest;
use crate::types::Vec3;
use serde_json::json;
use std::time::Duration;

pub fn spec() -> BehaviorSpec {
    BehaviorSpec::new(
        "navigate_to",
        "Plan a collision-free path on the drone's map to a point in any frame and fly it, \
         replanning when new obstacles block it",
        Resource::Motion,
        NavigateTo::new,
    )
}

/// How often the path ahead is checked against new map data.
const CHECK_PERIOD: Duration = Duration::from_millis(100);
/// Shortest time between two replans (a blocked path waits this long before the next plan).
const MIN_REPLAN_INTERVAL: Duration = Duration::from_millis(500);

/// Seconds of reaction assumed between seeing and braking (map update and control lag).
const REACTION_S: f64 = 0.3;
/// Distance (m) kept short of the end of the seen-free path.
const STOP_MARGIN_M: f64 = 0.15;
/// Seen-free length (m), beyond what cruising needs, before a guarded vehicle cruises again.
const CRUISE_HYSTERESIS_M: f64 = 0.5;
/// A guarded vehicle that gets no closer (m) for the longer of two sensing turns and this long
/// has stalled: unknown space ahead it cannot see from where it is.
const STALL_PROGRESS_M: f64 = 0.1;
const STALL_MIN_S: f64 = 8.0;
/// Unknown cells this close (m) to a seen obstacle are planned around as obstacle: the side of
/// a pole the beams have not reached yet cannot be seen before flying past it.
const SHADOW_M: f64 = 0.3;
/// Stalls before giving up; each replans with unknown space ten times dearer.
const MAX_STALLS: u32 = 3;

/// Flying only where the sensors have looked (`unknown: sensed`).
#[derive(Debug, Clone, Copy, Default)]
struct Guard {
    /// Holding short of unseen space and turning to look, rather than cruising.
    active: bool,
    /// Seen-free length ahead at the last check (m).
    clear_m: f64,
    stalls: u32,
    /// The last shadowed plan found no path: plan without the shadow.
    unshadowed: bool,
    /// Least remaining length while guarded (m) and when it last shrank.
    best_remaining_m: f64,
    best_at: Duration,
}

/// A plan asked for and not answered yet.
struct Pending {
    ticket: Ticket,
    /// Planned with unknown space near obstacles as obstacle ([`SHADOW_M`]).
    shadowed: bool,
    /// Where the vehicle holds meanwhile.
    hold: MotionReference,
}

pub struct NavigateTo {
    goal: NavigateToGoal,
    /// The goal in `earth`, fixed at activation.
    target: Vec3,
    /// The child's yaw settings in `earth`.
    yaw_args: YawArgs,
    path: Option<NavPath>,
    child: Option<Box<dyn Behavior>>,
    pending: Option<Pending>,
    replans: u32,
    checked_revision: u64,
    checked_at: Duration,
    planned_at: Duration,
    guard: Guard,
}

impl NavigateTo {
    fn new(goal: NavigateToGoal) -> Self {
        Self {
            goal,
            target: Vec3::zeros(),
            yaw_args: YawArgs::default(),
            path: None,
            child: None,
            pending: None,
            replans: 0,
            checked_revision: 0,
            checked_at: Duration::ZERO,
            planned_at: Duration::ZERO,
            guard: Guard::default(),
        }
    }

    /// The planner's extra cost of unknown cells: the goal's, ten times dearer per stall.
    fn unknown_cost(&self) -> f64 {
        if self.guard.stalls == 0 {
            return self.goal.unknown_cost;
        }
        (self.goal.unknown_cost.max(1.0) * 10f64.powi(self.guard.stalls as i32))
            .min(MAX_UNKNOWN_EXTRA_COST)
    }

    /// Seen-free length (m) needed to cruise at the goal's speed: reaction, braking, margin.
    fn cruise_clear_m(&self, ctx: &BehaviorContext) -> f64 {
        let v = self.goal.speed;
        v * REACTION_S + v * v / (2.0 * braking_mps2(ctx)) + STOP_MARGIN_M
    }

    /// With `unknown: sensed`, the reference while the path ahead is not seen far enough to
    /// cruise: creep to the end of what is seen free, turning to look; `None` while cruising
    /// (the `follow_path` child flies). Leaving the guard restarts the child from here.
    fn guard(&mut self, ctx: &BehaviorContext) -> Result<Option<MotionReference>, Failure> {
        let (Some(map), Some(path)) = (ctx.map, self.path.as_ref()) else {
            return Ok(None);
        };
        let here = ctx.position();
        let need_m = self.cruise_clear_m(ctx);
        let clear = path.clear_ahead(
            &here,
            map.grid(),
            map.occupied_threshold(),
            self.goal.safety_distance,
            need_m + CRUISE_HYSTERESIS_M,
        );
        self.guard.clear_m = clear.clear_m;
        let remaining_m = path.remaining_m(&here);
        if self.guard.active {
            if clear.to_goal || clear.clear_m >= need_m + CRUISE_HYSTERESIS_M {
                self.guard.active = false;
                let ahead = path.ahead().to_vec();
                self.fly(ctx, &ahead)?;
                return Ok(None);
            }
        } else if clear.to_goal || clear.clear_m >= need_m {
            return Ok(None);
        } else {
            self.guard.active = true;
            self.guard.best_remaining_m = remaining_m;
            self.guard.best_at = ctx.now;
            self.child = None;
        }
        if remaining_m < self.guard.best_remaining_m - STALL_PROGRESS_M {
            self.guard.best_remaining_m = remaining_m;
            self.guard.best_at = ctx.now;
        }
        let stall_s = (2.0 * std::f64::consts::TAU / self.goal.sense_rate).max(STALL_MIN_S);
        if seconds_since(ctx.now, self.guard.best_at) > stall_s {
            self.guard.stalls += 1;
            if self.guard.stalls > MAX_STALLS {
                let p = path.point_ahead(&here, clear.clear_m);
                return Err(super::progress::stuck(
                    ctx,
                    format!(
                        "cannot see the way ahead: space near ({:.1}, {:.1}) m stays unobserved \
                         from where the vehicle can safely go",
                        p.x, p.y
                    ),
                ));
            }
            self.guard.active = false;
            self.replans += 1;
            self.ask_plan(ctx, map);
            return Ok(Some(ctx.hold_here()));
        }
        let go_m = (clear.clear_m - STOP_MARGIN_M).max(0.0);
        let speed = (2.0 * braking_mps2(ctx) * go_m)
            .sqrt()
            .clamp(0.05, self.goal.speed);
        let rate = self.goal.spin_rate.unwrap_or(self.goal.sense_rate);
        Ok(Some(MotionReference::Position {
            position_enu_m: path.point_ahead(&here, go_m),
            velocity_ff_enu_mps: Vec3::zeros(),
            yaw: YawTarget::Rate(rate),
            max_speed_mps: speed,
        }))
    }

    /// What the map already says of the goal, read from the cells around it only: outside the
    /// map, occupied or within the safety distance of an obstacle, or unknown when unknown
    /// space is not to be flown. The planner checks the same on its own map; this catches it
    /// at start, before anything flies.
    fn goal_plausible(&self, map: &MapServer) -> Result<(), Failure> {
        let grid = map.grid();
        let spec = grid.spec();
        let goal = nalgebra::Vector2::new(self.target.x, self.target.y);
        let value = grid.get_at(goal).ok_or(PlanError::GoalOutsideMap)?;
        if self.goal.unknown == UnknownArg::Blocked && value < 0 {
            return Err(PlanError::GoalOccupied.into());
        }
        let radius_m = self.goal.safety_distance + spec.resolution_m;
        let steps = (radius_m / spec.resolution_m).ceil() as i64;
        for dy in -steps..=steps {
            for dx in -steps..=steps {
                let offset = nalgebra::Vector2::new(dx as f64, dy as f64) * spec.resolution_m;
                if offset.norm() > radius_m {
                    continue;
                }
                if map.is_occupied_at(goal + offset) == Some(true) {
                    return Err(PlanError::GoalOccupied.into());
                }
            }
        }
        Ok(())
    }

    fn request(&self, ctx: &BehaviorContext, resolution_m: f64) -> PlanRequest {
        PlanRequest {
            start_enu_m: ctx.position(),
            goal_enu_m: self.target,
            flight_height_m: self.target.z,
            safety_distance_m: self.goal.safety_distance + resolution_m,
            unknown: match self.goal.unknown {
                UnknownArg::Sensed | UnknownArg::Blind => {
                    UnknownPolicy::AllowedWithCost(self.unknown_cost())
                }
                UnknownArg::Blocked => UnknownPolicy::Blocked,
            },
            kind: self.goal.planner.into(),
            max_map_age_s: None,
            shadow_m: if self.shadowed() { SHADOW_M } else { 0.0 },
        }
    }

    /// Whether the next plan keeps off the unseen side of obstacles: when flying only what was
    /// seen, unless that found no path last time.
    fn shadowed(&self) -> bool {
        self.goal.unknown == UnknownArg::Sensed && !self.guard.unshadowed
    }

    /// Files a plan from here on the current map; the vehicle holds here until it arrives.
    fn ask_plan(&mut self, ctx: &BehaviorContext, map: &MapServer) {
        let request = self.request(ctx, map.grid().spec().resolution_m);
        let ticket = ctx.services.plan(request, map.snapshot());
        self.pending = Some(Pending {
            ticket,
            shadowed: self.shadowed(),
            hold: ctx.hold_here(),
        });
        self.child = None;
        self.checked_revision = map.revision();
        self.checked_at = ctx.now;
        self.planned_at = ctx.now;
    }

    /// Hands waypoints to a new `follow_path` child from here, built directly from its typed
    /// goal.
    fn fly(&mut self, ctx: &BehaviorContext, waypoints: &[Vec3]) -> Result<(), Failure> {
        let goal = FollowPathGoal {
            path: waypoints.iter().map(|p| [p.x, p.y, p.z]).collect(),
            speed: self.goal.speed,
            yaw: self.yaw_args.clone(),
            frame_id: Some(EARTH.to_string()),
        };
        goal.check()?;
        let mut child = FollowPath::new(goal);
        child.activate(ctx).map_err(|e| e.within("follow_path"))?;
        self.child = Some(Box::new(child));
        self.path = Some(NavPath::new(ctx.position(), waypoints));
        Ok(())
    }

    /// While a plan is pending: the hold, or the plan flown as soon as it arrived.
    fn wait_for_plan(&mut self, ctx: &BehaviorContext) -> Result<Option<MotionReference>, Failure> {
        let Some(pending) = self.pending.as_ref() else {
            return Ok(None);
        };
        match ctx.services.take_plan(&pending.ticket) {
            None => Ok(Some(pending.hold)),
            Some(Err(_)) if pending.shadowed => {
                // A gap that only looks closed from this side: plan through it and look.
                self.guard.unshadowed = true;
                if let Some(map) = ctx.map {
                    self.ask_plan(ctx, map);
                }
                Ok(Some(ctx.hold_here()))
            }
            Some(result) => {
                self.pending = None;
                let planned: PlannedPath = result?;
                self.guard.unshadowed = false;
                self.fly(ctx, &planned.waypoints_enu_m)?;
                self.guard.active = false;
                Ok(None)
            }
        }
    }

    /// Whether the map changed since the last check and now blocks the path ahead.
    fn path_blocked(&mut self, ctx: &BehaviorContext) -> bool {
        let (Some(map), Some(path)) = (ctx.map, self.path.as_ref()) else {
            return false;
        };
        if map.revision() == self.checked_revision
            || seconds_since(ctx.now, self.checked_at) < CHECK_PERIOD.as_secs_f64()
        {
            return false;
        }
        self.checked_revision = map.revision();
        self.checked_at = ctx.now;
        let resolution = map.grid().spec().resolution_m;
        // Where the vehicle already is cannot be avoided any more: only what lies ahead counts.
        let skip_m = self.goal.safety_distance + resolution;
        path.first_blocked(
            &ctx.position(),
            map.grid(),
            map.occupied_threshold(),
            self.goal.safety_distance,
            skip_m,
        )
        .is_some()
    }

    fn feedback(&self, ctx: &BehaviorContext) -> serde_json::Value {
        let here = ctx.position();
        let remaining = self
            .path
            .as_ref()
            .map_or((self.target - here).norm(), |p| p.remaining_m(&here));
        json!({
            "distance_remaining": remaining,
            "replans": self.replans,
            "estimated_time_remaining_s": remaining / self.goal.speed,
            "actual_speed": ctx.state.velocity_enu_mps.norm(),
            "planned_path": self.path.as_ref().map(NavPath::points_json).unwrap_or_default(),
            "planning": self.pending.is_some(),
            "sensing": self.guard.active,
            "seen_ahead_m": self.guard.clear_m,
        })
    }
}

/// Deceleration (m/s^2) the guard counts on: half the configured limit, leaving room for
/// tracking.
fn braking_mps2(ctx: &BehaviorContext) -> f64 {
    (0.5 * ctx.config.max_acceleration_mps2).max(0.1)
}

fn no_map() -> Failure {
    Failure::new(
        FailureCode::NoMap,
        "no map: mapping is off ([map] plugin = \"none\")",
    )
}

impl InFlight for NavigateTo {
    type Goal = NavigateToGoal;

    fn goal_enu_m(&self) -> Option<Vec3> {
        Some(self.target)
    }

    fn goal_mut(&mut self) -> &mut NavigateToGoal {
        &mut self.goal
    }

    /// Resolves the goal and the yaw in `earth`, refuses a goal the map already rules out, and
    /// asks for the first plan.
    fn start(&mut self, ctx: &BehaviorContext) -> Result<(), Failure> {
        let frame = frame_or_earth(&self.goal.frame_id);
        self.target = ctx
            .frames
            .point_to_earth(
                &Vec3::new(self.goal.x, self.goal.y, self.goal.z),
                &frame,
                ctx.now,
            )
            .map_err(|e| Failure::from(e).within("cannot resolve goal"))?;
        let yaw = |yaw_mode, yaw_angle, face_point| YawArgs {
            yaw_mode,
            yaw_angle,
            face_point,
        };
        self.yaw_args = if self.goal.spin_rate.is_some() {
            yaw(YawMode::PathFacing, None, None)
        } else {
            match self.goal.yaw.resolve(ctx, &frame)? {
                ResolvedYaw::Fixed(a) => yaw(YawMode::Fixed, Some(a), None),
                ResolvedYaw::PathFacing => yaw(YawMode::PathFacing, None, None),
                ResolvedYaw::Face(p) => yaw(YawMode::FacePoint, None, Some([p.x, p.y, p.z])),
            }
        };
        self.replans = 0;
        self.guard = Guard::default();
        let map = ctx.map.ok_or_else(no_map)?;
        self.goal_plausible(map)?;
        self.ask_plan(ctx, map);
        Ok(())
    }

    fn resume(&mut self, ctx: &BehaviorContext) {
        if let Some(c) = self.child.as_mut() {
            c.resume(ctx);
        }
    }

    fn run(&mut self, ctx: &BehaviorContext, requests: &mut Vec<PlatformRequest>) -> Step {
        let spin_rate = self.goal.spin_rate;
        let spin = move |r: MotionReference| match spin_rate {
            Some(rate) => with_yaw(r, YawTarget::Rate(rate)),
            None => r,
        };
        match self.wait_for_plan(ctx) {
            Err(e) => return Step::Failed(e),
            Ok(Some(hold)) => {
                return Step::Running {
                    reference: Some(spin(hold)),
                    feedback: self.feedback(ctx),
                }
            }
            Ok(None) => {}
        }
        if let Some(p) = self.path.as_mut() {
            p.advance(&ctx.position());
        }
        if seconds_since(ctx.now, self.planned_at) >= MIN_REPLAN_INTERVAL.as_secs_f64()
            && self.path_blocked(ctx)
        {
            if let Some(map) = ctx.map {
                self.replans += 1;
                self.ask_plan(ctx, map);
                return Step::Running {
                    reference: Some(spin(ctx.hold_here())),
                    feedback: self.feedback(ctx),
                };
            }
        }
        if self.goal.unknown == UnknownArg::Sensed {
            match self.guard(ctx) {
                Err(e) => return Step::Failed(e),
                Ok(Some(reference)) => {
                    return Step::Running {
                        reference: Some(reference),
                        feedback: self.feedback(ctx),
                    }
                }
                Ok(None) => {}
            }
        }
        let Some(child) = self.child.as_mut() else {
            return Step::Failed(Failure::new(
                FailureCode::Internal,
                "navigate_to was not activated",
            ));
        };
        match child.run(ctx, requests) {
            Step::Running { reference, .. } => Step::Running {
                reference: reference.map(spin),
                feedback: self.feedback(ctx),
            },
            Step::Succeeded => Step::Succeeded,
            Step::Failed(reason) => Step::Failed(reason.within("follow_path")),
        }
    }
}

/// The same reference with another heading target.
pub(crate) fn with_yaw(reference: MotionReference, yaw: YawTarget) -> MotionReference {
    match reference {
        MotionReference::Position {
            position_enu_m,
            velocity_ff_enu_mps,
            max_speed_mps,
            ..
        } => MotionReference::Position {
            position_enu_m,
            velocity_ff_enu_mps,
            yaw,
            max_speed_mps,
        },
        MotionReference::Velocity {
            velocity_enu_mps, ..
        } => MotionReference::Velocity {
            velocity_enu_mps,
            yaw,
        },
        MotionReference::Trajectory {
            position_enu_m,
            velocity_enu_mps,
            acceleration_enu_mps2,
            max_speed_mps,
            ..
        } => MotionReference::Trajectory {
            position_enu_m,
            velocity_enu_mps,
            acceleration_enu_mps2,
            yaw,
            max_speed_mps,
        },
    }
}
