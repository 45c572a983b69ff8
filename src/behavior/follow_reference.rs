//! `follow_reference`: track a point in a (possibly moving) frame with per-axis speed limits.
//! Never finishes by itself; stop it or start another motion behavior.

use super::goal::{
    check_finite, check_non_negative, frame_or_earth, FramedPoint, GoalError, InFlight,
    MovingTarget, ResolvedYaw, YawArgs,
};
use super::registry::{BehaviorSpec, Goal, Resource};
use super::{yaw_target, BehaviorContext, Failure, PathHeading, Step};
use crate::control::MotionReference;
use crate::types::PlatformRequest;
use crate::types::Vec3;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};
use serde_json::json;

#[derive(Debug, Clone, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct FollowReferenceGoal {
    pub x: f64,
    pub y: f64,
    pub z: f64,
    pub frame_id: String,
    /// Speed limits per axis (m/s); 0 = the vehicle limit.
    #[serde(default)]
    pub speed_x: f64,
    #[serde(default)]
    pub speed_y: f64,
    #[serde(default)]
    pub speed_z: f64,
    #[serde(flatten)]
    pub yaw: YawArgs,
}

impl Goal for FollowReferenceGoal {
    fn check(&self) -> Result<(), GoalError> {
        check_finite("x, y, z", &[self.x, self.y, self.z])?;
        // Each speed on its own, so the error (and its JSON pointer) names the one at fault.
        check_non_negative("speed_x", self.speed_x, "m/s")?;
        check_non_negative("speed_y", self.speed_y, "m/s")?;
        check_non_negative("speed_z", self.speed_z, "m/s")?;
        self.yaw.check()
    }
    fn targets(&self) -> Vec<FramedPoint> {
        vec![FramedPoint {
            position_m: Vec3::new(self.x, self.y, self.z),
            frame_id: frame_or_earth(&Some(self.frame_id.clone())),
        }]
    }
    fn speeds_mps(&self) -> Vec<f64> {
        vec![self.speed_x, self.speed_y, self.speed_z]
    }
}

pub fn spec() -> BehaviorSpec {
    BehaviorSpec::new(
        "follow_reference",
        "Track a point in a possibly moving frame until stopped",
        Resource::Motion,
        FollowReference::new,
    )
}

pub struct FollowReference {
    goal: FollowReferenceGoal,
    yaw: ResolvedYaw,
    last_target: MovingTarget,
    heading: PathHeading,
}

impl FollowReference {
    fn new(goal: FollowReferenceGoal) -> Self {
        Self {
            goal,
            yaw: ResolvedYaw::Fixed(0.0),
            last_target: MovingTarget::default(),
            heading: PathHeading::default(),
        }
    }
    fn target(&self, ctx: &BehaviorContext) -> Result<Vec3, Failure> {
        ctx.frames
            .point_to_earth(
                &Vec3::new(self.goal.x, self.goal.y, self.goal.z),
                &self.goal.frame_id,
                ctx.now,
            )
            .map_err(|e| Failure::from(e).within("cannot resolve reference"))
    }
}

impl InFlight for FollowReference {
    type Goal = FollowReferenceGoal;

    fn goal_mut(&mut self) -> &mut FollowReferenceGoal {
        &mut self.goal
    }

    /// Resolves the goal against frames and the vehicle's state, ready to fly it.
    fn start(&mut self, ctx: &BehaviorContext) -> Result<(), Failure> {
        self.target(ctx)?;
        self.yaw = self.goal.yaw.resolve(ctx, &self.goal.frame_id)?;
        Ok(())
    }

    fn run(&mut self, ctx: &BehaviorContext, _requests: &mut Vec<PlatformRequest>) -> Step {
        let target = match self.target(ctx) {
            Ok(t) => t,
            Err(e) => return Step::Failed(e),
        };
        let target_velocity = self.last_target.update(target, ctx.now);
        let max_speed = [self.goal.speed_x, self.goal.speed_y, self.goal.speed_z]
            .into_iter()
            .fold(0.0, f64::max);
        let max_speed = if max_speed > 0.0 {
            max_speed
        } else {
            f64::INFINITY
        };
        let reference = MotionReference::Position {
            position_enu_m: target,
            velocity_ff_enu_mps: target_velocity,
            yaw: yaw_target(
                &self.yaw,
                ctx,
                &mut self.heading,
                PathHeading::toward(&target, ctx),
            ),
            max_speed_mps: max_speed,
        };
        let feedback = json!({
            "actual_speed": ctx.state.velocity_enu_mps.norm(),
            "actual_distance_to_goal": (target - ctx.position()).norm(),
        });
        Step::Running {
            reference: Some(reference),
            feedback,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::behavior::registry::Goal;

    #[test]
    fn a_negative_speed_is_named_on_its_own() {
        let goal: FollowReferenceGoal = serde_json::from_value(serde_json::json!({
            "x": 0.0, "y": 0.0, "z": 2.0, "frame_id": "earth", "speed_x": 1.0, "speed_z": -0.5
        }))
        .unwrap();
        let error = goal.check().unwrap_err().to_string();
        assert!(error.starts_with("speed_z must be >= 0 m/s"), "{error}");
    }
}
