//! The behavior server: runs behaviors through their shared lifecycle, one per resource.
//!
//! Motion behaviors share the `motion` resource: starting one stops the one running (it ends
//! aborted, "preempted"). When no motion behavior runs, or one is paused, the server holds the
//! vehicle where it was, so stop, pause and failure all leave it hovering.

use super::registry::{ParsedGoal, Registry, Resource};
use super::{Behavior, BehaviorContext, Step};
use super::{Failure, FailureCode};
use crate::control::MotionReference;
use crate::types::PlatformRequest;
use serde::{Deserialize, Serialize};
use std::time::Duration;

pub type BehaviorId = u64;

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RunState {
    Running,
    Paused,
}

/// How a behavior ended. Serialised as `{"result": "succeeded"}` or
/// `{"result": "failed" | "aborted", "code": <stable code>, "reason": <message>}`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", tag = "result")]
pub enum BehaviorResult {
    Succeeded,
    Failed { code: FailureCode, reason: String },
    Aborted { code: FailureCode, reason: String },
}

impl BehaviorResult {
    pub fn failed(f: Failure) -> Self {
        BehaviorResult::Failed {
            code: f.code,
            reason: f.message,
        }
    }

    pub fn aborted(f: Failure) -> Self {
        BehaviorResult::Aborted {
            code: f.code,
            reason: f.message,
        }
    }

    /// Why it did not succeed (`None` when it did).
    pub fn reason(&self) -> Option<&str> {
        match self {
            BehaviorResult::Succeeded => None,
            BehaviorResult::Failed { reason, .. } | BehaviorResult::Aborted { reason, .. } => {
                Some(reason)
            }
        }
    }

    pub fn code(&self) -> Option<FailureCode> {
        match self {
            BehaviorResult::Succeeded => None,
            BehaviorResult::Failed { code, .. } | BehaviorResult::Aborted { code, .. } => {
                Some(*code)
            }
        }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", tag = "event")]
pub enum BehaviorEvent {
    Started {
        id: BehaviorId,
        behavior: String,
        goal: serde_json::Value,
    },
    Paused {
        id: BehaviorId,
        behavior: String,
    },
    Resumed {
        id: BehaviorId,
        behavior: String,
    },
    Modified {
        id: BehaviorId,
        behavior: String,
        goal: serde_json::Value,
    },
    Finished {
        id: BehaviorId,
        behavior: String,
        result: BehaviorResult,
    },
}

#[derive(Debug, Clone, thiserror::Error, PartialEq)]
pub enum ServerError {
    #[error("unknown behavior `{0}`")]
    UnknownBehavior(String),
    #[error("goal rejected by {behavior}: {reason}")]
    Rejected { behavior: String, reason: Failure },
    #[error("no running behavior with id {0}")]
    NotActive(BehaviorId),
    #[error("behavior {0} is not running")]
    NotRunning(BehaviorId),
    #[error("behavior {0} is not paused")]
    NotPaused(BehaviorId),
}

impl ServerError {
    /// The stable code clients switch on.
    pub fn code(&self) -> FailureCode {
        match self {
            ServerError::UnknownBehavior(_) => FailureCode::InvalidGoal,
            ServerError::Rejected { reason, .. } => reason.code,
            ServerError::NotActive(_) | ServerError::NotRunning(_) | ServerError::NotPaused(_) => {
                FailureCode::Internal
            }
        }
    }
}

/// How often an offboard claim is repeated while the autopilot has not switched yet.
const OFFBOARD_CLAIM_PERIOD: Duration = Duration::from_secs(1);

/// Asks for offboard for a behavior started outside it, until the autopilot is in it.
/// The fastest speed a goal asks for (m/s), if it asks any.
fn speed_cap(goal: &ParsedGoal) -> Option<f64> {
    goal.summary()
        .speeds_mps
        .iter()
        .copied()
        .filter(|v| v.is_finite() && *v > 0.0)
        .reduce(f64::max)
}

fn claim_offboard(a: &mut Active, ctx: &BehaviorContext, requests: &mut Vec<PlatformRequest>) {
    let Some(last) = a.claims_offboard else {
        return;
    };
    if ctx.platform.offboard {
        a.claims_offboard = None;
        return;
    }
    if last == Duration::ZERO || ctx.now.saturating_sub(last) >= OFFBOARD_CLAIM_PERIOD {
        requests.push(PlatformRequest::StartOffboard);
        a.claims_offboard = Some(ctx.now.max(Duration::from_nanos(1)));
    }
}

/// A snapshot of one active behavior, for status displays.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ActiveInfo {
    pub id: BehaviorId,
    pub behavior: String,
    pub state: RunState,
    pub goal: serde_json::Value,
    pub feedback: serde_json::Value,
    pub started_at_s: f64,
}

struct Active {
    info: ActiveInfo,
    resource: Resource,
    behavior: Box<dyn Behavior>,
    /// Where to hold while paused.
    hold: Option<MotionReference>,
    /// The fastest its goal asks for (m/s; `None`: it asks none): no reference it gives is
    /// flown faster, the holds it borrows (at `hold_speed_mps`) included.
    speed_cap_mps: Option<f64>,
    /// Started while airborne outside offboard (after a link loss, or a pilot's mode change
    /// followed by a new order): it asks the autopilot for offboard until it has it. A behavior
    /// that loses offboard while running never asks again: whoever took control keeps it.
    claims_offboard: Option<Duration>,
}

/// What one server tick produces.
#[derive(Debug, Default)]
pub struct ServerOutput {
    pub reference: Option<MotionReference>,
    pub requests: Vec<PlatformRequest>,
}

pub struct BehaviorServer {
    registry: Registry,
    active: Vec<Active>,
    next_id: BehaviorId,
    /// Hold reference used when no motion behavior is running.
    hold: Option<MotionReference>,
    events: Vec<BehaviorEvent>,
}

impl BehaviorServer {
    pub fn new(registry: Registry) -> Self {
        Self {
            registry,
            active: Vec::new(),
            next_id: 1,
            hold: None,
            events: Vec::new(),
        }
    }

    pub fn registry(&self) -> &Registry {
        &self.registry
    }

    /// Events since the last call, oldest first.
    pub fn drain_events(&mut self) -> Vec<BehaviorEvent> {
        std::mem::take(&mut self.events)
    }

    /// No behavior is running or paused.
    pub fn is_idle(&self) -> bool {
        self.active.is_empty()
    }

    pub fn active(&self) -> Vec<ActiveInfo> {
        self.active.iter().map(|a| a.info.clone()).collect()
    }

    /// The motion behavior running or paused (name) and the point it flies to, if one.
    pub fn motion(&self) -> Option<(&str, Option<crate::types::Vec3>)> {
        self.active
            .iter()
            .find(|a| a.resource == Resource::Motion)
            .map(|a| (a.info.behavior.as_str(), a.behavior.goal_enu_m()))
    }

    pub fn info(&self, id: BehaviorId) -> Option<&ActiveInfo> {
        self.active
            .iter()
            .find(|a| a.info.id == id)
            .map(|a| &a.info)
    }

    /// Parses the goal for behavior `name`, then starts it (see [`Self::start_parsed`]).
    pub fn start(
        &mut self,
        name: &str,
        goal: &serde_json::Value,
        ctx: &BehaviorContext,
    ) -> Result<BehaviorId, ServerError> {
        let parsed = self.parse(name, goal)?;
        self.start_parsed(&parsed, ctx)
    }

    /// Parses and checks `args` for behavior `name` without starting anything.
    pub fn parse(&self, name: &str, args: &serde_json::Value) -> Result<ParsedGoal, ServerError> {
        let spec = self
            .registry
            .get(name)
            .ok_or_else(|| ServerError::UnknownBehavior(name.to_string()))?;
        (spec.parse)(args).map_err(|reason| ServerError::Rejected {
            behavior: name.to_string(),
            reason,
        })
    }

    /// Creates the behavior of a parsed goal, lets it check the goal against the vehicle's
    /// state now, and starts it, preempting whatever held its resource.
    pub fn start_parsed(
        &mut self,
        goal: &ParsedGoal,
        ctx: &BehaviorContext,
    ) -> Result<BehaviorId, ServerError> {
        let name = goal.behavior();
        let spec = self
            .registry
            .get(name)
            .ok_or_else(|| ServerError::UnknownBehavior(name.to_string()))?;
        let rejected = |reason: Failure| ServerError::Rejected {
            behavior: name.to_string(),
            reason,
        };
        let mut behavior = (spec.create)(goal).map_err(rejected)?;
        behavior.activate(ctx).map_err(rejected)?;
        let resource = spec.resource;
        let preempted: Vec<BehaviorId> = self
            .active
            .iter()
            .filter(|a| a.resource == resource)
            .map(|a| a.info.id)
            .collect();
        for id in preempted {
            self.finish(
                id,
                BehaviorResult::aborted(Failure::new(
                    FailureCode::Preempted,
                    format!("preempted by {name}"),
                )),
                ctx,
            );
        }
        let id = self.next_id;
        self.next_id += 1;
        self.active.push(Active {
            info: ActiveInfo {
                id,
                behavior: name.to_string(),
                state: RunState::Running,
                goal: goal.args().clone(),
                feedback: serde_json::Value::Null,
                started_at_s: ctx.now.as_secs_f64(),
            },
            resource,
            behavior,
            hold: None,
            speed_cap_mps: speed_cap(goal),
            claims_offboard: (resource == Resource::Motion
                && ctx.is_flying()
                && !ctx.platform.offboard)
                .then_some(Duration::ZERO),
        });
        self.events.push(BehaviorEvent::Started {
            id,
            behavior: name.to_string(),
            goal: goal.args().clone(),
        });
        Ok(id)
    }

    pub fn pause(&mut self, id: BehaviorId, ctx: &BehaviorContext) -> Result<(), ServerError> {
        let a = self.find(id)?;
        if a.info.state != RunState::Running {
            return Err(ServerError::NotRunning(id));
        }
        a.info.state = RunState::Paused;
        a.hold = Some(ctx.hold_here());
        let behavior = a.info.behavior.clone();
        self.events.push(BehaviorEvent::Paused { id, behavior });
        Ok(())
    }

    pub fn resume(&mut self, id: BehaviorId, ctx: &BehaviorContext) -> Result<(), ServerError> {
        let a = self.find(id)?;
        if a.info.state != RunState::Paused {
            return Err(ServerError::NotPaused(id));
        }
        a.behavior.resume(ctx);
        a.info.state = RunState::Running;
        a.hold = None;
        let behavior = a.info.behavior.clone();
        self.events.push(BehaviorEvent::Resumed { id, behavior });
        Ok(())
    }

    /// Replaces the goal of a running or paused behavior; on refusal the old goal stays.
    pub fn modify(
        &mut self,
        id: BehaviorId,
        goal: &serde_json::Value,
        ctx: &BehaviorContext,
    ) -> Result<(), ServerError> {
        let name = self.find(id)?.info.behavior.clone();
        let parsed = self.parse(&name, goal)?;
        let a = self.find(id)?;
        a.behavior
            .modify(ctx, &parsed)
            .map_err(|reason| ServerError::Rejected {
                behavior: name.clone(),
                reason,
            })?;
        a.info.goal = goal.clone();
        a.speed_cap_mps = speed_cap(&parsed);
        self.events.push(BehaviorEvent::Modified {
            id,
            behavior: name,
            goal: goal.clone(),
        });
        Ok(())
    }

    /// Stops a behavior; it ends aborted and the vehicle holds where it is.
    pub fn stop(&mut self, id: BehaviorId, ctx: &BehaviorContext) -> Result<(), ServerError> {
        self.find(id)?;
        self.finish(
            id,
            BehaviorResult::aborted(Failure::new(FailureCode::Stopped, "stopped")),
            ctx,
        );
        Ok(())
    }

    /// Ends a behavior as done although it would go on (its time is up): it finishes
    /// succeeded and the vehicle holds where it is.
    pub fn complete(&mut self, id: BehaviorId, ctx: &BehaviorContext) -> Result<(), ServerError> {
        self.find(id)?;
        self.finish(id, BehaviorResult::Succeeded, ctx);
        Ok(())
    }

    /// Stops everything (link loss, emergency); each ends aborted with `reason`.
    pub fn stop_all(&mut self, reason: Failure, ctx: &BehaviorContext) {
        self.end_all(&BehaviorResult::aborted(reason), ctx);
    }

    /// Ends everything because the flight itself failed (a crash); each ends failed with `reason`.
    pub fn fail_all(&mut self, reason: Failure, ctx: &BehaviorContext) {
        self.end_all(&BehaviorResult::failed(reason), ctx);
    }

    fn end_all(&mut self, result: &BehaviorResult, ctx: &BehaviorContext) {
        let ids: Vec<BehaviorId> = self.active.iter().map(|a| a.info.id).collect();
        for id in ids {
            self.finish(id, result.clone(), ctx);
        }
    }

    fn find(&mut self, id: BehaviorId) -> Result<&mut Active, ServerError> {
        self.active
            .iter_mut()
            .find(|a| a.info.id == id)
            .ok_or(ServerError::NotActive(id))
    }

    fn finish(&mut self, id: BehaviorId, result: BehaviorResult, ctx: &BehaviorContext) {
        if let Some(pos) = self.active.iter().position(|a| a.info.id == id) {
            let a = self.active.remove(pos);
            if a.resource == Resource::Motion {
                self.hold = if !ctx.is_flying() {
                    None
                } else if result == BehaviorResult::Succeeded {
                    Some(ctx.hold_reached())
                } else {
                    Some(ctx.hold_here())
                };
            }
            self.events.push(BehaviorEvent::Finished {
                id,
                behavior: a.info.behavior,
                result,
            });
        }
    }

    /// Runs every active behavior once and picks the motion reference (capped at the speed
    /// its goal asks for).
    pub fn tick(&mut self, ctx: &BehaviorContext) -> ServerOutput {
        let mut out = ServerOutput::default();
        let mut finished = Vec::new();
        let mut motion_reference = None;
        let mut motion_active = false;
        for a in self.active.iter_mut() {
            if a.resource == Resource::Motion {
                motion_active = true;
            }
            if a.info.state == RunState::Paused {
                if a.resource == Resource::Motion {
                    motion_reference = a.hold;
                }
                continue;
            }
            match a.behavior.run(ctx, &mut out.requests) {
                Step::Running {
                    reference,
                    feedback,
                } => {
                    a.info.feedback = feedback;
                    if a.resource == Resource::Motion {
                        motion_reference = match (reference, a.speed_cap_mps) {
                            (Some(r), Some(cap)) => Some(r.at_most(cap)),
                            (r, _) => r,
                        };
                        if reference.is_some() {
                            claim_offboard(a, ctx, &mut out.requests);
                        }
                    }
                }
                Step::Succeeded => finished.push((a.info.id, BehaviorResult::Succeeded)),
                Step::Failed(reason) => finished.push((a.info.id, BehaviorResult::failed(reason))),
            }
        }
        for (id, result) in finished {
            self.finish(id, result, ctx);
        }
        let motion_still_active = self.active.iter().any(|a| a.resource == Resource::Motion);
        if !motion_still_active {
            if !ctx.is_flying() {
                self.hold = None;
            }
            motion_reference = self.hold;
        } else if !motion_active {
            motion_reference = self.hold;
        }
        out.reference = motion_reference;
        out
    }

    /// Forget the idle hold point (after landing, or when the platform took over).
    pub fn clear_hold(&mut self) {
        self.hold = None;
    }
}

/// Elapsed seconds between two instants, never negative.
pub fn seconds_since(now: Duration, then: Duration) -> f64 {
    now.saturating_sub(then).as_secs_f64()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::behavior::registry::{BehaviorSpec, Goal};
    use crate::behavior::testing::Scene as World;
    use crate::types::FlightStatus;
    use serde_json::json;

    /// Succeeds after `ticks` runs; counts how often it ran.
    #[derive(Clone, serde::Deserialize, schemars::JsonSchema)]
    struct CountGoal {
        ticks: u32,
        /// The speed the goal asks for, if any (its reference is a hold at 1 m/s).
        #[serde(default)]
        speed: Option<f64>,
    }
    impl Goal for CountGoal {
        fn check(&self) -> Result<(), crate::behavior::GoalError> {
            Ok(())
        }
        fn speeds_mps(&self) -> Vec<f64> {
            self.speed.into_iter().collect()
        }
    }
    struct Count {
        goal: CountGoal,
        runs: u32,
    }
    impl Behavior for Count {
        fn activate(&mut self, _ctx: &BehaviorContext) -> Result<(), Failure> {
            Ok(())
        }
        fn run(&mut self, ctx: &BehaviorContext, _requests: &mut Vec<PlatformRequest>) -> Step {
            self.runs += 1;
            if self.runs >= self.goal.ticks {
                Step::Succeeded
            } else {
                Step::Running {
                    reference: Some(MotionReference::hold(ctx.position(), 0.0, 1.0)),
                    feedback: json!({ "runs": self.runs }),
                }
            }
        }
    }

    fn server() -> BehaviorServer {
        let mut registry = Registry::empty();
        registry.register(BehaviorSpec::new(
            "count",
            "test behavior",
            Resource::Motion,
            |goal: CountGoal| Count { goal, runs: 0 },
        ));
        BehaviorServer::new(registry)
    }

    fn results(events: &[BehaviorEvent]) -> Vec<(BehaviorId, BehaviorResult)> {
        events
            .iter()
            .filter_map(|e| match e {
                BehaviorEvent::Finished { id, result, .. } => Some((*id, result.clone())),
                _ => None,
            })
            .collect()
    }

    fn offboard_requests(s: &mut BehaviorServer, w: &World, t_ms: u64) -> usize {
        s.tick(&w.ctx_at(Duration::from_millis(t_ms)))
            .requests
            .iter()
            .filter(|r| **r == PlatformRequest::StartOffboard)
            .count()
    }

    #[test]
    fn a_motion_behavior_started_outside_offboard_claims_it_until_it_has_it() {
        let mut w = World::flying();
        w.platform.offboard = false;
        let mut s = server();
        s.start("count", &json!({ "ticks": 1000 }), &w.ctx(0))
            .unwrap();
        assert_eq!(offboard_requests(&mut s, &w, 10), 1);
        assert_eq!(offboard_requests(&mut s, &w, 500), 0, "once a second");
        assert_eq!(offboard_requests(&mut s, &w, 1100), 1);
        w.platform.offboard = true;
        assert_eq!(offboard_requests(&mut s, &w, 2200), 0);
        w.platform.offboard = false;
        assert_eq!(
            offboard_requests(&mut s, &w, 3300),
            0,
            "offboard taken away while running: never grabbed back"
        );
    }

    #[test]
    fn a_motion_behavior_started_in_offboard_never_asks_for_it() {
        let w = World::flying();
        let mut s = server();
        s.start("count", &json!({ "ticks": 1000 }), &w.ctx(0))
            .unwrap();
        assert_eq!(offboard_requests(&mut s, &w, 10), 0);
    }

    fn max_speed(out: &ServerOutput) -> f64 {
        match out.reference {
            Some(MotionReference::Position { max_speed_mps, .. }) => max_speed_mps,
            ref other => panic!("{other:?}"),
        }
    }

    #[test]
    fn no_reference_is_flown_faster_than_its_goal_asks() {
        let w = World::flying();
        let mut s = server();
        s.start("count", &json!({ "ticks": 1000, "speed": 0.3 }), &w.ctx(0))
            .unwrap();
        assert_eq!(
            max_speed(&s.tick(&w.ctx(1))),
            0.3,
            "the hold at 1 m/s, capped"
        );
        let mut s = server();
        s.start("count", &json!({ "ticks": 1000 }), &w.ctx(0))
            .unwrap();
        assert_eq!(max_speed(&s.tick(&w.ctx(1))), 1.0, "a goal without a speed");
    }

    #[test]
    fn runs_until_success_then_holds() {
        let w = World::flying();
        let mut s = server();
        let id = s.start("count", &json!({ "ticks": 3 }), &w.ctx(0)).unwrap();
        for t in 1..=3 {
            assert!(s.tick(&w.ctx(t)).reference.is_some());
        }
        assert_eq!(
            results(&s.drain_events()),
            [(id, BehaviorResult::Succeeded)]
        );
        assert!(s.active().is_empty());
        assert!(s.tick(&w.ctx(4)).reference.is_some(), "holds after success");
    }

    #[test]
    fn paused_behaviors_do_not_run_and_resume_where_they_were() {
        let w = World::flying();
        let mut s = server();
        let id = s.start("count", &json!({ "ticks": 3 }), &w.ctx(0)).unwrap();
        s.tick(&w.ctx(1));
        s.pause(id, &w.ctx(1)).unwrap();
        assert_eq!(s.pause(id, &w.ctx(1)), Err(ServerError::NotRunning(id)));
        for t in 2..10 {
            assert!(s.tick(&w.ctx(t)).reference.is_some(), "holds while paused");
        }
        assert_eq!(s.info(id).unwrap().state, RunState::Paused);
        assert_eq!(s.info(id).unwrap().feedback, json!({ "runs": 1 }));
        s.resume(id, &w.ctx(10)).unwrap();
        assert_eq!(s.resume(id, &w.ctx(10)), Err(ServerError::NotPaused(id)));
        s.tick(&w.ctx(11));
        s.tick(&w.ctx(12));
        assert_eq!(
            results(&s.drain_events()),
            [(id, BehaviorResult::Succeeded)]
        );
    }

    #[test]
    fn a_new_motion_behavior_preempts_the_running_one() {
        let w = World::flying();
        let mut s = server();
        let first = s
            .start("count", &json!({ "ticks": 100 }), &w.ctx(0))
            .unwrap();
        let second = s
            .start("count", &json!({ "ticks": 100 }), &w.ctx(1))
            .unwrap();
        assert_eq!(
            results(&s.drain_events()),
            [(
                first,
                BehaviorResult::aborted(Failure::new(FailureCode::Preempted, "preempted by count"))
            )]
        );
        assert_eq!(s.active().len(), 1);
        assert_eq!(s.active()[0].id, second);
    }

    #[test]
    fn commands_name_what_is_wrong() {
        let w = World::flying();
        let mut s = server();
        assert_eq!(
            s.start("fly_to_the_moon", &json!({}), &w.ctx(0)),
            Err(ServerError::UnknownBehavior("fly_to_the_moon".into()))
        );
        assert!(matches!(
            s.start("count", &json!({ "ticks": "many" }), &w.ctx(0)),
            Err(ServerError::Rejected { .. })
        ));
        assert_eq!(s.stop(42, &w.ctx(0)), Err(ServerError::NotActive(42)));
        let id = s
            .start("count", &json!({ "ticks": 10 }), &w.ctx(0))
            .unwrap();
        let refused = s.modify(id, &json!({ "ticks": 2 }), &w.ctx(0));
        assert!(
            matches!(&refused, Err(ServerError::Rejected { reason, .. }) if reason.message.contains("cannot be modified")),
            "{refused:?}"
        );
        s.stop(id, &w.ctx(1)).unwrap();
        assert_eq!(
            results(&s.drain_events()),
            [(
                id,
                BehaviorResult::aborted(Failure::new(FailureCode::Stopped, "stopped"))
            )]
        );
    }

    #[test]
    fn a_completed_behavior_finishes_succeeded() {
        let w = World::flying();
        let mut s = server();
        let id = s
            .start("count", &json!({ "ticks": 100 }), &w.ctx(0))
            .unwrap();
        s.complete(id, &w.ctx(1)).unwrap();
        assert_eq!(
            results(&s.drain_events()),
            [(id, BehaviorResult::Succeeded)]
        );
        assert_eq!(s.complete(id, &w.ctx(2)), Err(ServerError::NotActive(id)));
    }

    #[test]
    fn on_the_ground_nothing_is_held() {
        let mut w = World::flying();
        let mut s = server();
        let id = s
            .start("count", &json!({ "ticks": 100 }), &w.ctx(0))
            .unwrap();
        w.platform.flight = FlightStatus::Landed;
        s.stop(id, &w.ctx(1)).unwrap();
        assert!(s.tick(&w.ctx(2)).reference.is_none());
    }
}
