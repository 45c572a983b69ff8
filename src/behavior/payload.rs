//! Payload behaviors used by missions when the build has no others: `point_gimbal` (gimbal
//! resource) and `take_photo` (camera resource). They only send platform requests, so they run
//! in parallel with motion behaviors (`wait: false`).
//!
//! In: goals and the vehicle state. Out: `PointGimbal` / `TakePhoto` platform requests.

use super::{
    check_non_negative, Behavior, BehaviorContext, BehaviorSpec, Failure, FailureCode, FramedPoint,
    Goal, GoalError, Registry, Resource, Step,
};
use crate::types::{wrap_angle_rad, Vec3};
use crate::types::{PlatformRequest, RequestRefused};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};
use serde_json::json;
use std::time::Duration;

/// The behaviors missions can use: the motion behaviors plus these payload ones, unless the
/// build registers its own under the same names.
pub fn registry() -> Registry {
    let mut r = Registry::with_motion_behaviors();
    if r.get("point_gimbal").is_none() {
        r.register(point_gimbal_spec());
    }
    if r.get("take_photo").is_none() {
        r.register(take_photo_spec());
    }
    r
}

#[derive(Debug, Clone, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct PointGimbalGoal {
    /// Point to look at (m) in `frame_id`.
    pub x: f64,
    pub y: f64,
    pub z: f64,
    /// Frame of the point; `earth` when absent.
    #[serde(default)]
    pub frame_id: Option<String>,
    /// Aerostack2's mode: 0 = point at the target (the only one supported).
    #[serde(default)]
    pub mode: u8,
    /// Keep pointing at the target as the vehicle moves, until stopped; false = point once.
    #[serde(default)]
    pub follow: bool,
}

fn frame_of(frame_id: &Option<String>) -> String {
    match frame_id {
        Some(f) if !f.is_empty() => f.clone(),
        _ => crate::estimator::frames::EARTH.to_string(),
    }
}

impl Goal for PointGimbalGoal {
    fn check(&self) -> Result<(), GoalError> {
        if ![self.x, self.y, self.z].iter().all(|v| v.is_finite()) {
            return Err(GoalError::NotFiniteIn {
                name: "x, y, z".into(),
                unit: "m".into(),
            });
        }
        if self.mode != 0 {
            return Err(GoalError::GimbalMode(self.mode));
        }
        Ok(())
    }
    fn targets(&self) -> Vec<FramedPoint> {
        // The vehicle does not fly to the point it looks at: only its frame is checked.
        Vec::new()
    }
}

fn point_gimbal_spec() -> BehaviorSpec {
    BehaviorSpec::new(
        "point_gimbal",
        "Point the gimbal at a point in any frame, once or following it",
        Resource::Gimbal,
        |goal: PointGimbalGoal| PointGimbal {
            goal,
            last: None,
            last_sent: None,
            acked: false,
        },
    )
}

pub struct PointGimbal {
    goal: PointGimbalGoal,
    last: Option<(f64, f64)>,
    last_sent: Option<Duration>,
    /// The autopilot acknowledged the last command sent.
    acked: bool,
}

const GIMBAL_PERIOD: Duration = Duration::from_millis(100);
/// A gimbal or camera command not acknowledged within this time fails the behavior.
const ACK_TIMEOUT: Duration = Duration::from_secs(5);

/// The outcome of a request of this kind among the acks of this tick, if any.
fn ack_of(
    ctx: &BehaviorContext,
    is_kind: impl Fn(&PlatformRequest) -> bool,
) -> Option<Result<(), RequestRefused>> {
    ctx.request_results
        .iter()
        .rev()
        .find(|r| is_kind(&r.request))
        .map(|r| r.outcome.clone())
}

impl PointGimbal {
    /// (pitch, yaw) in the body frame (FLU: positive pitch looks down), rad.
    fn angles(&self, ctx: &BehaviorContext) -> Result<(f64, f64), Failure> {
        let target = ctx.frames.point_to_earth(
            &Vec3::new(self.goal.x, self.goal.y, self.goal.z),
            &frame_of(&self.goal.frame_id),
            ctx.now,
        )?;
        let d = target - ctx.position();
        let pitch = (-d.z).atan2(d.xy().norm());
        let yaw = wrap_angle_rad(d.y.atan2(d.x) - ctx.yaw());
        Ok((pitch, yaw))
    }
}

impl Behavior for PointGimbal {
    fn activate(&mut self, ctx: &BehaviorContext) -> Result<(), Failure> {
        self.angles(ctx).map(|_| ())
    }

    fn run(&mut self, ctx: &BehaviorContext, requests: &mut Vec<PlatformRequest>) -> Step {
        let (pitch, yaw) = match self.angles(ctx) {
            Ok(a) => a,
            Err(e) => return Step::Failed(e),
        };
        let moved = self
            .last
            .is_none_or(|(p, y)| (p - pitch).abs() > 0.01 || wrap_angle_rad(y - yaw).abs() > 0.01);
        let due = self
            .last_sent
            .is_none_or(|t| ctx.now.saturating_sub(t) >= GIMBAL_PERIOD);
        match ack_of(ctx, |r| matches!(r, PlatformRequest::PointGimbal { .. })) {
            Some(Ok(())) => self.acked = true,
            Some(Err(reason)) => {
                return Step::Failed(Failure::new(
                    FailureCode::AutopilotRefused,
                    format!("gimbal command refused: {reason}"),
                ))
            }
            None => {}
        }
        if !self.goal.follow && self.acked {
            return Step::Succeeded;
        }
        if let Some(sent) = self.last_sent.filter(|_| !self.acked) {
            if ctx.now.saturating_sub(sent) > ACK_TIMEOUT {
                return Step::Failed(Failure::new(
                    FailureCode::AutopilotSilent,
                    "no answer to the gimbal command",
                ));
            }
        }
        let first = self.last.is_none();
        if first || (self.goal.follow && moved && due) {
            requests.push(PlatformRequest::PointGimbal {
                pitch_rad: pitch,
                yaw_rad: yaw,
            });
            self.last = Some((pitch, yaw));
            self.last_sent = Some(ctx.now);
            self.acked = false;
        }
        Step::Running {
            reference: None,
            feedback: json!({ "pitch_rad": pitch, "yaw_rad": yaw }),
        }
    }

    fn resume(&mut self, _ctx: &BehaviorContext) {
        self.last = None;
        self.acked = false;
    }
}

#[derive(Debug, Clone, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct TakePhotoGoal {
    /// Number of photos.
    #[serde(default = "one")]
    pub n: u32,
    /// Time between photos (s).
    #[serde(default = "half_second")]
    pub interval_s: f64,
}

/// The most photos one `take_photo` goal may ask for.
const MAX_PHOTOS: u32 = 10_000;

fn one() -> u32 {
    1
}
fn half_second() -> f64 {
    0.5
}

impl Goal for TakePhotoGoal {
    fn check(&self) -> Result<(), GoalError> {
        if self.n == 0 || self.n > MAX_PHOTOS {
            return Err(GoalError::PhotoCount {
                n: self.n,
                max: MAX_PHOTOS,
            });
        }
        check_non_negative("interval_s", self.interval_s, "s")
    }
}

fn take_photo_spec() -> BehaviorSpec {
    BehaviorSpec::new(
        "take_photo",
        "Take n photos, one every interval_s seconds",
        Resource::Camera,
        |goal: TakePhotoGoal| TakePhoto {
            goal,
            taken: 0,
            last: None,
            pending: None,
        },
    )
}

pub struct TakePhoto {
    goal: TakePhotoGoal,
    /// Photos the camera confirmed.
    taken: u32,
    last: Option<Duration>,
    /// When the capture waiting for its ack was requested.
    pending: Option<Duration>,
}

impl Behavior for TakePhoto {
    fn activate(&mut self, _ctx: &BehaviorContext) -> Result<(), Failure> {
        Ok(())
    }

    fn run(&mut self, ctx: &BehaviorContext, requests: &mut Vec<PlatformRequest>) -> Step {
        if let Some(asked) = self.pending {
            match ack_of(ctx, |r| matches!(r, PlatformRequest::TakePhoto)) {
                Some(Ok(())) => {
                    self.taken += 1;
                    self.pending = None;
                }
                Some(Err(reason)) => {
                    return Step::Failed(Failure::new(
                        FailureCode::AutopilotRefused,
                        format!("camera refused: {reason}"),
                    ))
                }
                None if ctx.now.saturating_sub(asked) > ACK_TIMEOUT => {
                    return Step::Failed(Failure::new(
                        FailureCode::AutopilotSilent,
                        "no answer to the capture command",
                    ));
                }
                None => {}
            }
        }
        if self.taken >= self.goal.n {
            return Step::Succeeded;
        }
        let due = self.last.is_none_or(|t| {
            ctx.now.saturating_sub(t) >= Duration::from_secs_f64(self.goal.interval_s)
        });
        if due && self.pending.is_none() {
            requests.push(PlatformRequest::TakePhoto);
            self.pending = Some(ctx.now);
            self.last = Some(ctx.now);
        }
        Step::Running {
            reference: None,
            feedback: json!({ "photos_taken": self.taken, "photos": self.goal.n }),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::behavior::testing::Scene;
    use crate::types::RequestResult;

    fn ack(request: PlatformRequest, outcome: Result<(), RequestRefused>) -> Vec<RequestResult> {
        vec![RequestResult { request, outcome }]
    }

    #[test]
    fn point_gimbal_succeeds_only_once_acknowledged() {
        let mut scene = Scene::flying();
        let mut b = point_gimbal_spec()
            .build(&json!({"x": 10.0, "y": 0.0, "z": 0.0}))
            .unwrap();
        b.activate(&scene.ctx(0)).unwrap();
        let mut requests = Vec::new();
        assert!(matches!(
            b.run(&scene.ctx(0), &mut requests),
            Step::Running { .. }
        ));
        let sent = requests.first().copied().unwrap();
        assert!(matches!(sent, PlatformRequest::PointGimbal { .. }));
        requests.clear();
        assert!(matches!(
            b.run(&scene.ctx(1), &mut requests),
            Step::Running { .. }
        ));
        assert!(requests.is_empty(), "one command, then wait for its ack");
        scene.request_results = ack(sent, Ok(()));
        assert_eq!(b.run(&scene.ctx(2), &mut requests), Step::Succeeded);
    }

    #[test]
    fn point_gimbal_fails_with_the_refusal_or_without_an_answer() {
        let mut scene = Scene::flying();
        let goal = json!({"x": 10.0, "y": 0.0, "z": 0.0});
        let mut b = point_gimbal_spec().build(&goal).unwrap();
        let mut requests = Vec::new();
        b.run(&scene.ctx(0), &mut requests);
        scene.request_results = ack(requests[0], Err("MAV_RESULT_DENIED".into()));
        match b.run(&scene.ctx(1), &mut requests) {
            Step::Failed(r) => assert!(r.message.contains("DENIED"), "{r}"),
            other => panic!("{other:?}"),
        }
        let scene = Scene::flying();
        let mut b = point_gimbal_spec().build(&goal).unwrap();
        b.run(&scene.ctx(0), &mut requests);
        assert!(matches!(
            b.run(&scene.ctx(4), &mut requests),
            Step::Running { .. }
        ));
        assert!(matches!(
            b.run(&scene.ctx(6), &mut requests),
            Step::Failed(_)
        ));
    }

    #[test]
    fn take_photo_counts_acknowledged_captures_only() {
        let mut scene = Scene::flying();
        let mut b = take_photo_spec()
            .build(&json!({"n": 2, "interval_s": 0.0}))
            .unwrap();
        let mut requests = Vec::new();
        b.run(&scene.ctx(0), &mut requests);
        b.run(&scene.ctx(1), &mut requests);
        assert_eq!(
            requests,
            [PlatformRequest::TakePhoto],
            "no second capture before the ack"
        );
        scene.request_results = ack(PlatformRequest::TakePhoto, Ok(()));
        b.run(&scene.ctx(2), &mut requests);
        assert_eq!(requests.len(), 2);
        let refused = ack(PlatformRequest::TakePhoto, Err("camera busy".into()));
        scene.request_results = refused;
        match b.run(&scene.ctx(3), &mut requests) {
            Step::Failed(r) => assert!(r.message.contains("camera busy"), "{r}"),
            other => panic!("{other:?}"),
        }
    }
}
