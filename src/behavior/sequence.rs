//! Composite behaviors: a sequence of registered behaviors run one after another, built from
//! the primitives (never copied from them). `rtl` = climb to a height, go_to home, then land.

use super::go_to::{GoTo, GoToGoal};
use super::goal::{check_positive, GoalError, YawArgs};
use super::land::{Land, LandGoal};
use super::registry::{BehaviorSpec, Goal, Resource};
use super::{Behavior, BehaviorContext, Failure, FailureCode, Step};
use crate::estimator::frames::EARTH;
use crate::types::PlatformRequest;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};
use serde_json::json;

/// Runs child behaviors in order; fails as soon as one fails.
pub struct Sequence {
    /// The children, built from their typed goals; each activates when its turn comes.
    plan: Vec<(&'static str, Box<dyn Behavior>)>,
    index: usize,
}

impl Sequence {
    pub fn new(plan: Vec<(&'static str, Box<dyn Behavior>)>) -> Self {
        Self { plan, index: 0 }
    }

    fn start_child(&mut self, ctx: &BehaviorContext) -> Result<(), Failure> {
        let (name, child) = self
            .plan
            .get_mut(self.index)
            .ok_or_else(|| Failure::new(FailureCode::Internal, "sequence is empty"))?;
        child.activate(ctx).map_err(|e| e.within(name))
    }

    fn child_name(&self) -> &'static str {
        self.plan.get(self.index).map(|(n, _)| *n).unwrap_or("")
    }
}

impl Behavior for Sequence {
    fn activate(&mut self, ctx: &BehaviorContext) -> Result<(), Failure> {
        self.index = 0;
        self.start_child(ctx)
    }

    fn resume(&mut self, ctx: &BehaviorContext) {
        if let Some((_, c)) = self.plan.get_mut(self.index) {
            c.resume(ctx);
        }
    }

    fn run(&mut self, ctx: &BehaviorContext, requests: &mut Vec<PlatformRequest>) -> Step {
        let name = self.child_name();
        let Some((_, child)) = self.plan.get_mut(self.index) else {
            return Step::Failed(Failure::new(FailureCode::Internal, "no active step"));
        };
        match child.run(ctx, requests) {
            Step::Running {
                reference,
                feedback,
            } => {
                let feedback =
                    json!({ "step": name, "step_index": self.index, "step_feedback": feedback });
                Step::Running {
                    reference,
                    feedback,
                }
            }
            Step::Failed(reason) => Step::Failed(reason.within(name)),
            Step::Succeeded => {
                self.index += 1;
                if self.index >= self.plan.len() {
                    return Step::Succeeded;
                }
                if let Err(e) = self.start_child(ctx) {
                    return Step::Failed(e);
                }
                Step::Running {
                    reference: Some(ctx.hold_here()),
                    feedback: json!({ "step": self.child_name(), "step_index": self.index }),
                }
            }
        }
    }
}

#[derive(Debug, Clone, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct RtlGoal {
    /// Height to fly home at (m, in `earth`).
    pub height: f64,
    /// Cruise speed (m/s).
    pub speed: f64,
    /// Descent speed (m/s).
    #[serde(default = "default_land_speed")]
    pub land_speed: f64,
}

fn default_land_speed() -> f64 {
    0.5
}

impl Goal for RtlGoal {
    fn check(&self) -> Result<(), GoalError> {
        check_positive("height", self.height, "metres")?;
        check_positive("speed", self.speed, "m/s")?;
        check_positive("land_speed", self.land_speed, "m/s")
    }
    fn speeds_mps(&self) -> Vec<f64> {
        vec![self.speed, self.land_speed]
    }
    fn heights_m(&self) -> Vec<f64> {
        vec![self.height]
    }
}

pub fn rtl_spec() -> BehaviorSpec {
    BehaviorSpec::new(
        "rtl",
        "Return to the arming point at a height, then land",
        Resource::Motion,
        Rtl::new,
    )
}

/// `rtl`: resolves home when it starts, then runs go_to + land as a [`Sequence`].
pub struct Rtl {
    goal: RtlGoal,
    sequence: Option<Sequence>,
}

impl Rtl {
    fn new(goal: RtlGoal) -> Self {
        Self {
            goal,
            sequence: None,
        }
    }
}

impl Behavior for Rtl {
    fn activate(&mut self, ctx: &BehaviorContext) -> Result<(), Failure> {
        let home = ctx.home_enu_m.ok_or_else(|| {
            Failure::new(
                FailureCode::NotReady,
                "no home position: the vehicle has not armed",
            )
        })?;
        // Climb first (never descend) to the return height, fly home level, then land.
        let here = ctx.position();
        let cruise_z = (home.z + self.goal.height).max(here.z);
        let go = |x: f64, y: f64| -> (&'static str, Box<dyn Behavior>) {
            let goal = GoToGoal {
                x,
                y,
                z: cruise_z,
                speed: self.goal.speed,
                yaw: YawArgs::default(),
                frame_id: Some(EARTH.to_string()),
            };
            ("go_to", Box::new(GoTo::new(goal)))
        };
        let mut plan = Vec::new();
        if cruise_z - here.z > ctx.config.goal_threshold_m {
            plan.push(go(here.x, here.y));
        }
        plan.push(go(home.x, home.y));
        let land = LandGoal {
            speed: self.goal.land_speed,
        };
        plan.push(("land", Box::new(Land::new(land))));
        let mut sequence = Sequence::new(plan);
        sequence.activate(ctx)?;
        self.sequence = Some(sequence);
        Ok(())
    }

    fn resume(&mut self, ctx: &BehaviorContext) {
        if let Some(s) = self.sequence.as_mut() {
            s.resume(ctx);
        }
    }

    fn run(&mut self, ctx: &BehaviorContext, requests: &mut Vec<PlatformRequest>) -> Step {
        match self.sequence.as_mut() {
            Some(s) => s.run(ctx, requests),
            None => Step::Failed(Failure::new(FailureCode::Internal, "rtl was not activated")),
        }
    }
}
