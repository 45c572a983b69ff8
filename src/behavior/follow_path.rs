//! `follow_path`: fly a smooth trajectory through waypoints without stopping between them.

use super::arrival::Arrival;
use super::goal::{
    check_finite, check_positive, frame_or_earth, FramedPoint, GoalError, InFlight, ResolvedYaw,
    YawArgs,
};
use super::progress::Progress;
use super::registry::{BehaviorSpec, Goal, Resource};
use super::{
    heading_reached, yaw_target, BehaviorContext, Failure, FailureCode, PathHeading, Step,
};
use crate::control::trajectory::{PathTrajectory, TrajectoryLimits};
use crate::control::MotionReference;
use crate::types::PlatformRequest;
use crate::types::Vec3;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};
use serde_json::json;
use std::time::Duration;

#[derive(Debug, Clone, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct FollowPathGoal {
    /// Waypoints [x, y, z] (m) in `frame_id`.
    pub path: Vec<[f64; 3]>,
    /// Cruise speed (m/s).
    pub speed: f64,
    #[serde(flatten)]
    pub yaw: YawArgs,
    #[serde(default)]
    pub frame_id: Option<String>,
}

impl Goal for FollowPathGoal {
    fn check(&self) -> Result<(), GoalError> {
        if self.path.is_empty() {
            return Err(GoalError::EmptyPath);
        }
        for (i, p) in self.path.iter().enumerate() {
            check_finite(&format!("path[{i}]"), p)?;
        }
        check_positive("speed", self.speed, "m/s")?;
        self.yaw.check()
    }
    fn targets(&self) -> Vec<FramedPoint> {
        let frame_id = frame_or_earth(&self.frame_id);
        self.path
            .iter()
            .map(|&[x, y, z]| FramedPoint {
                position_m: Vec3::new(x, y, z),
                frame_id: frame_id.clone(),
            })
            .collect()
    }
    fn speeds_mps(&self) -> Vec<f64> {
        vec![self.speed]
    }
}

pub fn spec() -> BehaviorSpec {
    BehaviorSpec::new(
        "follow_path",
        "Fly through waypoints on a smooth, speed- and acceleration-limited trajectory",
        Resource::Motion,
        FollowPath::new,
    )
}

pub struct FollowPath {
    goal: FollowPathGoal,
    /// Waypoints in `earth`, fixed at activation (and on modify).
    waypoints: Vec<Vec3>,
    /// Index in `waypoints` of the first not yet passed.
    next: usize,
    trajectory: Option<PathTrajectory>,
    yaw: ResolvedYaw,
    heading: PathHeading,
    /// How far is left (path, then the distance to its end), to fail when stuck.
    progress: Progress,
    arrival: Arrival,
}

impl FollowPath {
    pub(crate) fn new(goal: FollowPathGoal) -> Self {
        Self {
            goal,
            waypoints: Vec::new(),
            next: 0,
            trajectory: None,
            yaw: ResolvedYaw::Fixed(0.0),
            heading: PathHeading::default(),
            progress: Progress::toward_point(Duration::ZERO),
            arrival: Arrival::at_goal(),
        }
    }

    /// Plans the trajectory from where the vehicle is through the waypoints not yet passed.
    fn plan(&mut self, ctx: &BehaviorContext) {
        let limits = TrajectoryLimits {
            cruise_speed_mps: ctx.planned_speed_mps(self.goal.speed),
            max_acceleration_mps2: ctx.config.max_acceleration_mps2,
            ..TrajectoryLimits::default()
        };
        let remaining = self.waypoints.get(self.next..).unwrap_or(&[]);
        let trajectory = PathTrajectory::moving(
            ctx.position(),
            ctx.state.velocity_enu_mps,
            remaining,
            limits,
        );
        self.progress = Progress::toward_point(ctx.now);
        self.trajectory = Some(trajectory);
    }
}

impl InFlight for FollowPath {
    type Goal = FollowPathGoal;

    fn goal_enu_m(&self) -> Option<Vec3> {
        self.waypoints.last().copied()
    }

    fn goal_mut(&mut self) -> &mut FollowPathGoal {
        &mut self.goal
    }

    fn start(&mut self, ctx: &BehaviorContext) -> Result<(), Failure> {
        let frame = frame_or_earth(&self.goal.frame_id);
        self.waypoints = self
            .goal
            .path
            .iter()
            .map(|&[x, y, z]| {
                ctx.frames
                    .point_to_earth(&Vec3::new(x, y, z), &frame, ctx.now)
                    .map_err(|e| Failure::from(e).within("cannot resolve path"))
            })
            .collect::<Result<_, _>>()?;
        self.yaw = self.goal.yaw.resolve(ctx, &frame)?;
        self.next = 0;
        self.plan(ctx);
        Ok(())
    }

    fn resume(&mut self, ctx: &BehaviorContext) {
        self.arrival.reset();
        self.plan(ctx);
    }

    fn run(&mut self, ctx: &BehaviorContext, _requests: &mut Vec<PlatformRequest>) -> Step {
        let Some(trajectory) = self.trajectory.as_mut() else {
            return Step::Failed(Failure::new(FailureCode::Internal, "no trajectory"));
        };
        let sample = trajectory.advance(ctx.dt_s, &ctx.position());
        // Waypoints count as passed when the vehicle comes within the threshold.
        while let Some(w) = self.waypoints.get(self.next) {
            if (w - ctx.position()).norm() < ctx.config.waypoint_threshold_m
                && self.next + 1 < self.waypoints.len()
            {
                self.next += 1;
            } else {
                break;
            }
        }
        let last = self
            .waypoints
            .last()
            .copied()
            .unwrap_or_else(|| ctx.position());
        let distance_to_end = (last - ctx.position()).norm();
        // The reference waits for a lagging vehicle, so a vehicle that cannot follow shows as a
        // path that stops getting shorter; once the reference is at the end, as a distance to
        // the end that stops shrinking.
        let remaining_m = trajectory.remaining_m();
        let left_m = remaining_m.max(distance_to_end);
        let stuck_s = self
            .progress
            .update(left_m, ctx.config.goal_threshold_m, ctx.now);
        if stuck_s > ctx.config.no_progress_timeout_s {
            return Step::Failed(super::progress::stuck(
                ctx,
                format!(
                    "no progress for {:.0} s (within 0.5 m of the goal, 3 s count as 1), {remaining_m:.2} m of path left, {distance_to_end:.2} m from its end",
                    ctx.config.no_progress_timeout_s
                ),
            ));
        }
        let within = sample.finished
            && distance_to_end < ctx.config.goal_threshold_m
            && heading_reached(&self.yaw, ctx);
        if self.arrival.update(within, ctx) {
            return Step::Succeeded;
        }
        let next_point = self.waypoints.get(self.next).copied().unwrap_or(last);
        // Path facing: along the reference's motion, held near the end and while it is slow.
        let along = (sample.velocity_enu_mps.xy().norm() > 0.05
            && (last - ctx.position()).xy().norm() > super::PATH_FACING_HOLD_M)
            .then_some(sample.velocity_enu_mps);
        let reference = MotionReference::Trajectory {
            position_enu_m: sample.position_enu_m,
            velocity_enu_mps: sample.velocity_enu_mps,
            acceleration_enu_mps2: sample.acceleration_enu_mps2,
            yaw: yaw_target(&self.yaw, ctx, &mut self.heading, along),
            max_speed_mps: self.goal.speed,
        };
        let feedback = json!({
            "actual_speed": ctx.state.velocity_enu_mps.norm(),
            "actual_distance_to_next_waypoint": (next_point - ctx.position()).norm(),
            "remaining_waypoints": self.waypoints.len().saturating_sub(self.next),
            "next_waypoint_id": self.next.to_string(),
        });
        Step::Running {
            reference: Some(reference),
            feedback,
        }
    }
}
