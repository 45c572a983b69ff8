//! `hover`: hold position, for `duration` seconds or until stopped.

use super::goal::{check_non_negative, GoalError};
use super::registry::{BehaviorSpec, Goal, Resource};
use super::server::seconds_since;
use super::{Behavior, BehaviorContext, Failure, Step};
use crate::control::MotionReference;
use crate::types::PlatformRequest;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};
use serde_json::json;
use std::time::Duration;

#[derive(Debug, Clone, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct HoverGoal {
    /// How long to hover (s); absent = until stopped.
    #[serde(default)]
    pub duration: Option<f64>,
}

impl Goal for HoverGoal {
    fn check(&self) -> Result<(), GoalError> {
        match self.duration {
            Some(d) => check_non_negative("duration", d, "s"),
            None => Ok(()),
        }
    }
}

pub fn spec() -> BehaviorSpec {
    BehaviorSpec::new(
        "hover",
        "Hold the current position, for a time or until stopped",
        Resource::Motion,
        Hover::new,
    )
}

pub struct Hover {
    goal: HoverGoal,
    hold: Option<MotionReference>,
    started: Duration,
}

impl Hover {
    fn new(goal: HoverGoal) -> Self {
        Self {
            goal,
            hold: None,
            started: Duration::ZERO,
        }
    }
}

impl Behavior for Hover {
    fn activate(&mut self, ctx: &BehaviorContext) -> Result<(), Failure> {
        if !ctx.is_flying() {
            return Err(Failure::not_flying());
        }
        self.hold = Some(ctx.hold_here());
        self.started = ctx.now;
        Ok(())
    }

    fn resume(&mut self, ctx: &BehaviorContext) {
        self.hold = Some(ctx.hold_here());
    }

    fn run(&mut self, ctx: &BehaviorContext, _requests: &mut Vec<PlatformRequest>) -> Step {
        let elapsed = seconds_since(ctx.now, self.started);
        if self.goal.duration.is_some_and(|d| elapsed >= d) {
            return Step::Succeeded;
        }
        Step::Running {
            reference: self.hold,
            feedback: json!({ "elapsed_s": elapsed }),
        }
    }
}
