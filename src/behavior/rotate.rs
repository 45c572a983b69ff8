//! `rotate`: turn in place to a heading (`yaw_angle`, in `frame_id`) or by an angle (`by_angle`)
//! at `yaw_speed`.

use super::goal::{check_positive, frame_or_earth, GoalError, InFlight};
use super::registry::{BehaviorSpec, Goal, Resource};
use super::{BehaviorContext, Failure, Step};
use crate::control::{MotionReference, YawTarget};
use crate::types::PlatformRequest;
use crate::types::{wrap_angle_rad, Vec3};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};
use serde_json::json;

#[derive(Debug, Clone, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct RotateGoal {
    /// Heading to reach (rad, CCW from the frame's x axis).
    #[serde(default)]
    pub yaw_angle: Option<f64>,
    /// Angle to turn by (rad, CCW positive), instead of `yaw_angle`.
    #[serde(default)]
    pub by_angle: Option<f64>,
    /// Turn rate (rad/s).
    #[serde(default = "default_yaw_speed")]
    pub yaw_speed: f64,
    #[serde(default)]
    pub frame_id: Option<String>,
}

fn default_yaw_speed() -> f64 {
    0.5
}

impl Goal for RotateGoal {
    fn check(&self) -> Result<(), GoalError> {
        match (self.yaw_angle, self.by_angle) {
            (Some(_), Some(_)) => return Err(GoalError::BothAngles),
            (None, None) => return Err(GoalError::NoAngle),
            (Some(a), None) | (None, Some(a)) if !a.is_finite() => {
                return Err(GoalError::AngleNotFinite)
            }
            _ => {}
        }
        check_positive("yaw_speed", self.yaw_speed, "rad/s")
    }
}

pub fn spec() -> BehaviorSpec {
    BehaviorSpec::new(
        "rotate",
        "Turn in place to a heading or by an angle",
        Resource::Motion,
        Rotate::new,
    )
}

pub struct Rotate {
    goal: RotateGoal,
    position: Vec3,
    /// Heading still to turn (rad, signed), consumed at yaw_speed.
    remaining_rad: f64,
    commanded_rad: f64,
}

impl Rotate {
    fn new(goal: RotateGoal) -> Self {
        Self {
            goal,
            position: Vec3::zeros(),
            remaining_rad: 0.0,
            commanded_rad: 0.0,
        }
    }
}

impl InFlight for Rotate {
    type Goal = RotateGoal;

    fn goal_mut(&mut self) -> &mut RotateGoal {
        &mut self.goal
    }

    fn start(&mut self, ctx: &BehaviorContext) -> Result<(), Failure> {
        self.position = ctx.position();
        self.commanded_rad = ctx.yaw();
        self.remaining_rad = match (self.goal.yaw_angle, self.goal.by_angle) {
            (Some(angle), _) => {
                let target = ctx.frames.yaw_to_earth(
                    angle,
                    &frame_or_earth(&self.goal.frame_id),
                    ctx.now,
                )?;
                wrap_angle_rad(target - ctx.yaw())
            }
            (None, Some(by)) => by,
            (None, None) => return Err(Failure::invalid("give yaw_angle or by_angle")),
        };
        Ok(())
    }

    fn resume(&mut self, ctx: &BehaviorContext) {
        self.position = ctx.position();
    }

    fn run(&mut self, ctx: &BehaviorContext, _requests: &mut Vec<PlatformRequest>) -> Step {
        let step = (self.goal.yaw_speed * ctx.dt_s).min(self.remaining_rad.abs())
            * self.remaining_rad.signum();
        self.commanded_rad += step;
        self.remaining_rad -= step;
        let error = wrap_angle_rad(self.commanded_rad - ctx.yaw());
        if self.remaining_rad.abs() < 1e-9 && error.abs() < 0.03 {
            return Step::Succeeded;
        }
        let reference = MotionReference::Position {
            position_enu_m: self.position,
            velocity_ff_enu_mps: Vec3::zeros(),
            yaw: YawTarget::Angle(wrap_angle_rad(self.commanded_rad)),
            max_speed_mps: ctx.config.hold_speed_mps,
        };
        Step::Running {
            reference: Some(reference),
            feedback: json!({ "remaining_angle_rad": self.remaining_rad + error }),
        }
    }
}
