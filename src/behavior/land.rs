//! `land`: descend at `speed` until touchdown, then disarm.
//!
//! Touchdown is the platform's landed state, or (for platforms without a land detector) no
//! descent for one second after at least 0.2 m of descent.

use super::registry::{BehaviorSpec, Goal, Resource};
use super::server::seconds_since;
use super::{goal::check_positive, Behavior, BehaviorContext, Failure, FailureCode, Step};
use crate::control::MotionReference;
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
    fn check(&self) -> Result<(), String> {
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
}

/// Disarming must be confirmed within this time after touchdown.
const DISARM_TIMEOUT_S: f64 = 5.0;

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
        self.hold_xy = ctx.position();
        self.yaw_rad = ctx.yaw();
        self.start_z = ctx.position().z;
        Ok(())
    }

    fn resume(&mut self, ctx: &BehaviorContext) {
        self.hold_xy = ctx.position();
        self.still_since = None;
    }

    fn run(&mut self, ctx: &BehaviorContext, requests: &mut Vec<PlatformRequest>) -> Step {
        let feedback = json!({
            "actual_land_height": ctx.position().z,
            "actual_land_speed": ctx.state.velocity_enu_mps.z,
        });
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
            return Step::Running {
                reference: None,
                feedback,
            };
        }
        if !ctx.platform.armed {
            // The autopilot disarmed by itself after its own touchdown detection.
            return Step::Succeeded;
        }
        if ctx.capabilities.native_land {
            if !self.requested_native {
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
            return Step::Running {
                reference: None,
                feedback,
            };
        }
        // A target far below the ground: the controller's speed limit sets the descent rate.
        let target = Vec3::new(self.hold_xy.x, self.hold_xy.y, ctx.position().z - 10.0);
        let reference = MotionReference::hold(target, self.yaw_rad, self.goal.speed);
        Step::Running {
            reference: Some(reference),
            feedback,
        }
    }
}

impl Land {
    fn touched_down(&mut self, ctx: &BehaviorContext) -> bool {
        if ctx.platform.flight == FlightStatus::Landed {
            return true;
        }
        let descended = self.start_z - ctx.position().z > 0.2;
        let still = ctx.state.velocity_enu_mps.z.abs() < 0.2 * self.goal.speed;
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
        // Descending: a reference below, never a disarm.
        scene.set_position(Vec3::new(1.0, 2.0, 1.0), Vec3::new(0.0, 0.0, -0.5));
        let (step, requests) = run(&mut land, &scene, ms(2000));
        assert!(requests.is_empty());
        match step {
            Step::Running {
                reference: Some(MotionReference::Position { position_enu_m, .. }),
                ..
            } => assert!(position_enu_m.z < 0.0 && position_enu_m.x == 1.0),
            other => panic!("{other:?}"),
        }
        // On the ground (the platform still says flying): still for a second, then disarm.
        scene.set_position(Vec3::new(1.0, 2.0, 0.0), Vec3::zeros());
        assert!(run(&mut land, &scene, ms(4000)).1.is_empty());
        assert!(run(&mut land, &scene, ms(4500)).1.is_empty());
        let (_, requests) = run(&mut land, &scene, ms(5100));
        assert_eq!(requests, [PlatformRequest::Disarm]);
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
        assert_eq!(requests, [PlatformRequest::Disarm]);
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
}
