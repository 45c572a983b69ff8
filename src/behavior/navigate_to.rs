//! `navigate_to`: plan a path on the drone's map to a goal in any frame and fly it through
//! `follow_path`, replanning when new map data blocks the path ahead (Aerostack2's
//! `path_planner` behavior, `NavigateToPoint`).
//!
//! In: the goal (point, speed, yaw, planner, safety distance, unknown-cell policy, optional spin)
//! and each tick the context with the drone's map. Out: the `follow_path` child's reference
//! (yaw replaced by a turn rate when spinning) and feedback `distance_remaining`, `replans`,
//! `estimated_time_remaining_s`, `planned_path`. Plans happen on activation and when the path
//! ahead is blocked, never every tick; no path fails (or rejects) with the planner's reason.

use super::goal::{
    check_finite, check_positive, frame_or_earth, parse_args, FramedPoint, ResolvedYaw, YawArgs,
};
use super::nav_path::NavPath;
use super::registry::{BehaviorSpec, Goal, Resource};
use super::server::seconds_since;
use super::{Behavior, BehaviorContext, Step};
use crate::control::{MotionReference, YawTarget};
use crate::planning::{
    PathPlanner, PlanBudget, PlanError, PlanRequest, PlannedPath, PlannerKind, Planners,
    UnknownPolicy, MAX_UNKNOWN_EXTRA_COST,
};
use crate::platform::PlatformRequest;
use crate::types::Vec3;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};
use serde_json::json;
use std::time::Duration;

/// The planner, by Aerostack2's plugin names.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum PlannerArg {
    /// Shortest path (A* on the grid).
    #[default]
    AStar,
    /// Shortest path, exhaustive search.
    Dijkstra,
    /// Largest clearance (along the Voronoi diagram).
    Voronoi,
    /// A* on the topological graph (`[map] graph`).
    GraphAStar,
}

impl From<PlannerArg> for PlannerKind {
    fn from(p: PlannerArg) -> Self {
        match p {
            PlannerArg::AStar => PlannerKind::AStar,
            PlannerArg::Dijkstra => PlannerKind::Dijkstra,
            PlannerArg::Voronoi => PlannerKind::Voronoi,
            PlannerArg::GraphAStar => PlannerKind::GraphAStar,
        }
    }
}

/// What unknown (never observed) cells are to the planner.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum UnknownArg {
    /// Crossable at `unknown_cost` extra: the vehicle flies into unmapped space and replans as
    /// obstacles appear.
    #[default]
    Allowed,
    /// Obstacles: only mapped free space is flown.
    Blocked,
}

#[derive(Debug, Clone, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct NavigateToGoal {
    /// Goal (m) in `frame_id`; `z` is the height of the whole path.
    pub x: f64,
    pub y: f64,
    pub z: f64,
    /// Cruise speed (m/s).
    pub speed: f64,
    #[serde(flatten)]
    pub yaw: YawArgs,
    /// Frame of the goal, resolved once when the behavior starts; `earth` when absent.
    #[serde(default)]
    pub frame_id: Option<String>,
    #[serde(default)]
    pub planner: PlannerArg,
    /// Least distance (m) between the vehicle's centre and mapped obstacles. Paths are planned
    /// one map cell wider; the path ahead is replanned when an obstacle appears within it.
    #[serde(default = "default_safety_distance")]
    pub safety_distance: f64,
    #[serde(default)]
    pub unknown: UnknownArg,
    /// Extra cost of crossing an unknown cell, relative to a free one (0..=1000).
    #[serde(default = "default_unknown_cost")]
    pub unknown_cost: f64,
    /// Turn continuously at this rate (rad/s, CCW positive) while flying, so that sparse range
    /// sensors (a four-beam multi-ranger) sweep all around; overrides `yaw_mode`.
    #[serde(default)]
    pub spin_rate: Option<f64>,
}

fn default_safety_distance() -> f64 {
    0.5
}

fn default_unknown_cost() -> f64 {
    1.0
}

impl Goal for NavigateToGoal {
    fn check(&self) -> Result<(), String> {
        check_finite("x, y, z", &[self.x, self.y, self.z])?;
        check_positive("speed", self.speed, "m/s")?;
        if !(self.safety_distance.is_finite() && self.safety_distance >= 0.0) {
            return Err(format!(
                "safety_distance must be >= 0 metres, got {}",
                self.safety_distance
            ));
        }
        if !(0.0..=MAX_UNKNOWN_EXTRA_COST).contains(&self.unknown_cost) {
            return Err(format!(
                "unknown_cost must be in 0..={MAX_UNKNOWN_EXTRA_COST}, got {}",
                self.unknown_cost
            ));
        }
        if let Some(rate) = self.spin_rate {
            check_finite("spin_rate", &[rate])?;
        }
        self.yaw.check()
    }
    fn targets(&self) -> Vec<FramedPoint> {
        vec![FramedPoint {
            position_m: Vec3::new(self.x, self.y, self.z),
            frame_id: frame_or_earth(&self.frame_id),
        }]
    }
    fn speeds_mps(&self) -> Vec<f64> {
        vec![self.speed]
    }
}

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

pub struct NavigateTo {
    goal: NavigateToGoal,
    planners: Planners,
    /// The goal in `earth`, fixed at activation.
    target: Vec3,
    /// The child's yaw settings in `earth`.
    yaw_args: serde_json::Value,
    path: Option<NavPath>,
    child: Option<Box<dyn Behavior>>,
    replans: u32,
    checked_revision: u64,
    checked_at: Duration,
    planned_at: Duration,
}

impl NavigateTo {
    fn new(goal: NavigateToGoal) -> Self {
        Self {
            goal,
            planners: Planners::default(),
            target: Vec3::zeros(),
            yaw_args: json!({}),
            path: None,
            child: None,
            replans: 0,
            checked_revision: 0,
            checked_at: Duration::ZERO,
            planned_at: Duration::ZERO,
        }
    }

    /// Resolves the goal and the yaw in `earth`, then plans and starts flying.
    fn start(&mut self, ctx: &BehaviorContext) -> Result<(), String> {
        let frame = frame_or_earth(&self.goal.frame_id);
        self.target = ctx
            .frames
            .point_to_earth(
                &Vec3::new(self.goal.x, self.goal.y, self.goal.z),
                &frame,
                ctx.now,
            )
            .map_err(|e| format!("cannot resolve goal: {e}"))?;
        self.yaw_args = if self.goal.spin_rate.is_some() {
            json!({ "yaw_mode": "path_facing" })
        } else {
            match self.goal.yaw.resolve(ctx, &frame)? {
                ResolvedYaw::Fixed(a) => json!({ "yaw_mode": "fixed", "yaw_angle": a }),
                ResolvedYaw::PathFacing => json!({ "yaw_mode": "path_facing" }),
                ResolvedYaw::Face(p) => {
                    json!({ "yaw_mode": "face_point", "face_point": [p.x, p.y, p.z] })
                }
            }
        };
        self.replans = 0;
        self.fly_new_plan(ctx).map_err(|e| e.to_string())
    }

    fn request(&self, ctx: &BehaviorContext, resolution_m: f64) -> PlanRequest {
        PlanRequest {
            start_enu_m: ctx.position(),
            goal_enu_m: self.target,
            flight_height_m: self.target.z,
            safety_distance_m: self.goal.safety_distance + resolution_m,
            unknown: match self.goal.unknown {
                UnknownArg::Allowed => UnknownPolicy::AllowedWithCost(self.goal.unknown_cost),
                UnknownArg::Blocked => UnknownPolicy::Blocked,
            },
            kind: self.goal.planner.into(),
            max_map_age_s: None,
        }
    }

    /// Plans from here on the current map and hands the path to a new `follow_path` child.
    fn fly_new_plan(&mut self, ctx: &BehaviorContext) -> Result<(), NavError> {
        let map = ctx.map.ok_or(NavError::NoMap)?;
        let planning = map.planning_map();
        let grid = planning.grid();
        let budget = PlanBudget::expansions(grid.spec().cell_count().saturating_mul(4));
        let request = self.request(ctx, grid.spec().resolution_m);
        let path: PlannedPath = self.planners.plan(&request, &planning, &budget)?;
        let waypoints: Vec<[f64; 3]> = path
            .waypoints_enu_m
            .iter()
            .map(|p| [p.x, p.y, p.z])
            .collect();
        let mut goal = json!({ "path": waypoints, "speed": self.goal.speed, "frame_id": "earth" });
        if let (Some(g), Some(y)) = (goal.as_object_mut(), self.yaw_args.as_object()) {
            g.extend(y.clone());
        }
        let spec = super::follow_path::spec();
        let mut child = (spec.create)(&goal).map_err(NavError::FollowPath)?;
        child.activate(ctx).map_err(NavError::FollowPath)?;
        self.child = Some(child);
        self.path = Some(NavPath::new(ctx.position(), &path.waypoints_enu_m));
        self.checked_revision = map.revision();
        self.checked_at = ctx.now;
        self.planned_at = ctx.now;
        Ok(())
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
        })
    }
}

/// Why navigation cannot go on.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
enum NavError {
    #[error("no map: mapping is off ([map] plugin = \"none\")")]
    NoMap,
    #[error("no path to the goal: {0}")]
    Plan(#[from] PlanError),
    #[error("follow_path: {0}")]
    FollowPath(String),
}

impl Behavior for NavigateTo {
    fn activate(&mut self, ctx: &BehaviorContext) -> Result<(), String> {
        if !ctx.is_flying() {
            return Err("platform is not flying".into());
        }
        self.start(ctx)
    }

    fn modify(&mut self, ctx: &BehaviorContext, args: &serde_json::Value) -> Result<(), String> {
        let goal: NavigateToGoal = parse_args(args)?;
        goal.check()?;
        let previous = std::mem::replace(&mut self.goal, goal);
        if let Err(e) = self.start(ctx) {
            self.goal = previous;
            return Err(e);
        }
        Ok(())
    }

    fn resume(&mut self, ctx: &BehaviorContext) {
        if let Some(c) = self.child.as_mut() {
            c.resume(ctx);
        }
    }

    fn run(&mut self, ctx: &BehaviorContext, requests: &mut Vec<PlatformRequest>) -> Step {
        if let Some(p) = self.path.as_mut() {
            p.advance(&ctx.position());
        }
        if seconds_since(ctx.now, self.planned_at) >= MIN_REPLAN_INTERVAL.as_secs_f64()
            && self.path_blocked(ctx)
        {
            self.replans += 1;
            if let Err(e) = self.fly_new_plan(ctx) {
                return Step::Failed(e.to_string());
            }
        }
        let Some(child) = self.child.as_mut() else {
            return Step::Failed("navigate_to was not activated".into());
        };
        match child.run(ctx, requests) {
            Step::Running { reference, .. } => {
                let reference = match (reference, self.goal.spin_rate) {
                    (Some(r), Some(rate)) => Some(with_yaw(r, YawTarget::Rate(rate))),
                    (r, _) => r,
                };
                Step::Running {
                    reference,
                    feedback: self.feedback(ctx),
                }
            }
            Step::Succeeded => Step::Succeeded,
            Step::Failed(reason) => Step::Failed(format!("follow_path: {reason}")),
        }
    }
}

/// The same reference with another heading target.
fn with_yaw(reference: MotionReference, yaw: YawTarget) -> MotionReference {
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
            ..
        } => MotionReference::Trajectory {
            position_enu_m,
            velocity_enu_mps,
            acceleration_enu_mps2,
            yaw,
        },
    }
}
