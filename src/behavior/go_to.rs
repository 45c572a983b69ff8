//! `go_to`: fly to a point in any frame (a moving frame is tracked), and `go_to_gps`.

use super::arrival::Arrival;
use super::goal::{
    check_finite, check_positive, frame_or_earth, FramedPoint, GoalError, InFlight, MovingTarget,
    ResolvedYaw, YawArgs,
};
use super::progress::Progress;
use super::registry::{BehaviorSpec, Goal, Resource};
use super::{
    heading_reached, yaw_target, BehaviorContext, Failure, FailureCode, PathHeading, Step,
};
use crate::control::MotionReference;
use crate::estimator::frames::EARTH;
use crate::types::GeoPoint;
use crate::types::PlatformRequest;
use crate::types::Vec3;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};
use serde_json::json;
use std::time::Duration;

#[derive(Debug, Clone, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct GoToGoal {
    /// Target (m) in `frame_id`.
    pub x: f64,
    pub y: f64,
    pub z: f64,
    /// Cruise speed (m/s).
    pub speed: f64,
    #[serde(flatten)]
    pub yaw: YawArgs,
    /// Frame of the target; `earth` when absent.
    #[serde(default)]
    pub frame_id: Option<String>,
}

impl Goal for GoToGoal {
    fn check(&self) -> Result<(), GoalError> {
        check_finite("x, y, z", &[self.x, self.y, self.z])?;
        check_positive("speed", self.speed, "m/s")?;
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

#[derive(Debug, Clone, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct GoToGpsGoal {
    /// WGS84 latitude and longitude (deg), altitude above mean sea level (m).
    pub lat: f64,
    pub lon: f64,
    pub alt: f64,
    /// Cruise speed (m/s).
    pub speed: f64,
    #[serde(flatten)]
    pub yaw: YawArgs,
}

impl Goal for GoToGpsGoal {
    fn check(&self) -> Result<(), GoalError> {
        GeoPoint {
            lat_deg: self.lat,
            lon_deg: self.lon,
            alt_m: self.alt,
        }
        .validate()?;
        check_positive("speed", self.speed, "m/s")?;
        self.yaw.check()
    }
    fn targets(&self) -> Vec<FramedPoint> {
        vec![FramedPoint {
            position_m: Vec3::new(self.lat, self.lon, self.alt),
            frame_id: super::goal::WGS84.into(),
        }]
    }
    fn speeds_mps(&self) -> Vec<f64> {
        vec![self.speed]
    }
}

pub fn spec() -> BehaviorSpec {
    BehaviorSpec::new(
        "go_to",
        "Fly to a point given in any frame; a point in a moving frame is tracked",
        Resource::Motion,
        GoTo::new,
    )
}

pub fn gps_spec() -> BehaviorSpec {
    BehaviorSpec::new(
        "go_to_gps",
        "Fly to a WGS84 latitude, longitude and altitude (AMSL)",
        Resource::Motion,
        |g: GoToGpsGoal| {
            GoTo::new(GoToGoal {
                x: g.lat,
                y: g.lon,
                z: g.alt,
                speed: g.speed,
                yaw: g.yaw,
                frame_id: Some(super::goal::WGS84.into()),
            })
        },
    )
}

pub struct GoTo {
    goal: GoToGoal,
    yaw: ResolvedYaw,
    last_target: MovingTarget,
    heading: PathHeading,
    progress: Progress,
    arrival: Arrival,
}

impl GoTo {
    pub(crate) fn new(goal: GoToGoal) -> Self {
        Self {
            goal,
            yaw: ResolvedYaw::Fixed(0.0),
            last_target: MovingTarget::default(),
            heading: PathHeading::default(),
            progress: Progress::toward_point(Duration::ZERO),
            arrival: Arrival::at_goal(),
        }
    }

    /// The goal in `earth` now.
    fn target(&self, ctx: &BehaviorContext) -> Result<Vec3, Failure> {
        let frame = frame_or_earth(&self.goal.frame_id);
        let point = Vec3::new(self.goal.x, self.goal.y, self.goal.z);
        if frame == super::goal::WGS84 {
            let geo = GeoPoint {
                lat_deg: point.x,
                lon_deg: point.y,
                alt_m: point.z,
            };
            return ctx
                .geo_origin
                .to_enu(&geo)
                .map_err(|e| Failure::new(FailureCode::FrameUnresolved, e.to_string()));
        }
        ctx.frames
            .point_to_earth(&point, &frame, ctx.now)
            .map_err(|e| Failure::from(e).within("cannot resolve goal"))
    }
}

impl InFlight for GoTo {
    type Goal = GoToGoal;

    fn goal_enu_m(&self) -> Option<Vec3> {
        self.last_target.position()
    }

    fn goal_mut(&mut self) -> &mut GoToGoal {
        &mut self.goal
    }

    /// Resolves the goal against frames and the vehicle's state, ready to fly it.
    fn start(&mut self, ctx: &BehaviorContext) -> Result<(), Failure> {
        let frame = frame_or_earth(&self.goal.frame_id);
        let yaw_frame = if frame == super::goal::WGS84 {
            EARTH.to_string()
        } else {
            frame
        };
        self.yaw = self.goal.yaw.resolve(ctx, &yaw_frame)?;
        let target = self.target(ctx)?;
        self.progress = Progress::toward_point(ctx.now);
        self.progress.update(
            (target - ctx.position()).norm(),
            ctx.config.goal_threshold_m,
            ctx.now,
        );
        self.last_target.reset();
        Ok(())
    }

    fn resume(&mut self, ctx: &BehaviorContext) {
        self.progress.restart(ctx.now);
        self.last_target.reset();
        self.arrival.reset();
    }

    fn run(&mut self, ctx: &BehaviorContext, _requests: &mut Vec<PlatformRequest>) -> Step {
        let target = match self.target(ctx) {
            Ok(t) => t,
            Err(e) => return Step::Failed(e),
        };
        // Velocity of the target itself (non-zero in a moving frame), used as feed-forward.
        let target_velocity = self.last_target.update(target, ctx.now);
        let distance = (target - ctx.position()).norm();
        let within = distance < ctx.config.goal_threshold_m && heading_reached(&self.yaw, ctx);
        if self.arrival.update(within, ctx) {
            return Step::Succeeded;
        }
        let stuck_s = self
            .progress
            .update(distance, ctx.config.goal_threshold_m, ctx.now);
        if stuck_s > ctx.config.no_progress_timeout_s {
            return Step::Failed(super::progress::stuck(
                ctx,
                format!(
                    "no progress for {:.0} s (within 0.5 m of the goal, 3 s count as 1), {distance:.2} m from the goal",
                    ctx.config.no_progress_timeout_s
                ),
            ));
        }
        let reference = MotionReference::Position {
            position_enu_m: target,
            velocity_ff_enu_mps: target_velocity,
            yaw: yaw_target(
                &self.yaw,
                ctx,
                &mut self.heading,
                PathHeading::toward(&target, ctx),
            ),
            max_speed_mps: self.goal.speed,
        };
        let feedback = json!({
            "actual_speed": ctx.state.velocity_enu_mps.norm(),
            "actual_distance_to_goal": distance,
        });
        Step::Running {
            reference: Some(reference),
            feedback,
        }
    }
}
