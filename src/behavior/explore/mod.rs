//! `explore`: one drone's part of a cooperative frontier exploration (the thesis's explorer:
//! init, sense, navigate to a frontier, drone avoidance, end), composed from the primitives:
//! `takeoff` when on the ground, `follow_path` to each frontier, `land` at the end.
//!
//! In: the goal (height, speed, spin rate, safety distances, allocator) and each tick the
//! context: the fleet view (for the drone watcher) and the allocator's answers. Out: the
//! children's references with the heading replaced by a steady turn (the four beams sweep all
//! around while the drone flies, so there is no stop to sense; clockwise or counter-clockwise as
//! the allocator says, so the side the unknown lies on is swept best), feedback `phase`, `goal`,
//! `frontiers`, `allocations`, `given_up`.
//!
//! A long frontier is flown along from end to end (`sweep_along`), so the beams clear it on the
//! way instead of while the drone waits at its middle; one sweep usually ends where the next
//! begins, and the known space grows in bands about a beam range wide. While the estimate
//! drifts, paths are flown no faster than the turning beams see ahead
//! ([`ExploreGoal::cruise_mps`]).
//!
//! The drone asks the fleet's frontier allocator (a service: asked on one tick, answered on a
//! later one) for a goal and the path to it through space observed free with the safety
//! distance all around (plus how far this drone has lately strayed across its path,
//! `exploration::online::tracking`, so an autopilot whose own hold wanders is kept that much farther
//! away), so it never flies where it has not seen; it asks again every
//! `retarget_period` s and whenever it arrives, so it re-targets without stopping; a path its
//! own map shows an obstacle on (within half the safety distance ahead: news the plan did not
//! have, as a drifting estimate brings) is dropped at once and asked again. A frontier
//! it sat next to for a quarter turn without it going away is given up (an occluded pocket).
//! A map correction's step (`BehaviorContext::map_step_m`) moves the point it hovers on with it,
//! and one of 0.2 m or more drops the path and asks again; while the safety stage holds it for a
//! peer (`BehaviorContext::safety_override`) its reference running ahead is not straying.
//! The exploration ends for this drone when the allocator has nothing for it and no other drone
//! holds a frontier, once it has flown to one (it turns all the time, so its beams swept all
//! around on the way) and has a path to every frontier left or has turned a quarter turn where
//! it is; before that, or while others hold frontiers, after a quarter turn of sensing and until
//! a failed drone's claims would have lapsed. It then lands (`land_when_done`; first back along
//! its own track when another drone, flying or landed, is within 1.5 m) and the behavior
//! succeeds.
//! When another flying drone comes closer than `drone_safety_distance` at the same height, the
//! one nearer its goal climbs 1 m (or as far as it gets in 8 s: a drone already up there may
//! stop it) and holds until they are 1.2 times that apart, then returns.
//!
//! The parts: [`goal`] (the arguments), [`ask`] (questions to the allocator and its answers),
//! [`blocked`] (the path watched on the map), [`end`] (the end rule), [`give_way`] (drone
//! avoidance), [`landing`] (where it lands); the phases run the registered primitives
//! (`takeoff`, `follow_path`, `land`) as children.

mod ask;
mod blocked;
mod end;
mod give_way;
mod goal;
mod landing;
#[cfg(test)]
mod tests;

pub use goal::{ExploreGoal, HeadingMode};

use super::follow_path::{FollowPath, FollowPathGoal};
use super::goal::{YawArgs, YawMode};
use super::navigate_to::with_yaw;
use super::progress::lost_peer;
use super::registry::{BehaviorSpec, Goal, Resource};
use super::services::Ticket;
use super::takeoff::{Takeoff, TakeoffGoal};
use super::{Behavior, BehaviorContext, Failure, FailureCode, Step};
use crate::control::{MotionReference, YawTarget};
use crate::estimator::frames::EARTH;
use crate::exploration::online::tracking::TrackingMargin;
use crate::safety::OverrideKind;
use crate::types::{PlatformRequest, Vec3};
use nalgebra::Vector2;
use serde_json::json;
use std::time::Duration;

pub fn spec() -> BehaviorSpec {
    BehaviorSpec::new(
        "explore",
        "Explore the unknown area with the fleet until no frontier is left: fly to the frontier \
         the fleet's allocator gives, through observed free space only, sweeping the sensors, \
         then land",
        Resource::Motion,
        Explore::new,
    )
}

/// Shortest time between two questions to the allocator.
const MIN_ASK_INTERVAL: Duration = Duration::from_millis(500);
/// Closer than this to its goal, a drone asks for the next one (m).
const NEAR_GOAL_M: f64 = 1.5;
/// A drone that moved less than this ...
const STUCK_RADIUS_M: f64 = 1.0;
/// ... for a quarter turn plus this long gives its goal up.
const STUCK_EXTRA_S: f64 = 2.0;
/// For this long after the safety stage last held the drone for a peer, its reference running
/// ahead is the hold's, not a stray (s): the stage lets go as the peer moves or reports again.
const PEER_GRACE_S: f64 = 5.0;
/// A map correction's step this long or longer (m) drops the path being flown: it was planned
/// from where the map had the drone before, and following it now would fly the step in truth,
/// through space nobody saw.
const MAP_STEP_M: f64 = 0.2;

enum Phase {
    TakingOff(Box<dyn Behavior>),
    Exploring,
    /// Out of another drone's way above `hold` (since `since`), then back down to it.
    GivingWay {
        hold: Vec3,
        returning: bool,
        since: Duration,
    },
    /// Back along its own track to a place clear of the other drones, to land there.
    Relocating(Box<dyn Behavior>),
    Landing(Box<dyn Behavior>),
}

pub struct Explore {
    goal: ExploreGoal,
    phase: Phase,
    /// Exploration height (ENU z, m).
    base_z: f64,
    /// Flying to this goal through `child`.
    target: Option<Vec3>,
    child: Option<Box<dyn Behavior>>,
    pending: Option<Ticket>,
    asked_at: Option<Duration>,
    /// Where the drone was when it asked: the answer's path starts there.
    asked_from: Vec3,
    /// Since when the allocator has had nothing for this drone.
    done_since: Option<Duration>,
    /// Where and since when the drone has stayed within `STUCK_RADIUS_M`.
    anchor: (Vec3, Duration),
    give_up: Option<Vector2<f64>>,
    frontiers: usize,
    allocations: u32,
    given_up: u32,
    /// When exploring started (after the takeoff).
    started_at: Duration,
    /// Where it flew, newest last (for a landing spot clear of the others).
    crumbs: Vec<Vec3>,
    /// Turn clockwise (the allocator's choice for the current sweep).
    clockwise: bool,
    /// How far the drone strays from its path: room added to the safety distance.
    tracking: TrackingMargin,
    /// The point it hovers on while it has no path to fly.
    hover_at: Option<Vec3>,
    /// The path flown, dropped when the map shows an obstacle on it.
    watch: blocked::PathWatch,
    /// Asked, at its end, whether anything is left within the room kept for straying (the
    /// extra room it kept, m).
    probing: Option<f64>,
    /// Since when it has found frontiers only within that room, waiting to hold its path again.
    boxed_since: Option<Duration>,
    /// Frontiers it ended with that it could have reached only within that room (it ends
    /// anyway, and says so).
    left_within_room: Option<usize>,
    /// When the safety stage last held it for a peer (a silent one, or one too close).
    kept_for_peer_at: Option<Duration>,
}

impl Explore {
    fn new(goal: ExploreGoal) -> Self {
        Self {
            goal,
            phase: Phase::Exploring,
            base_z: 0.0,
            target: None,
            child: None,
            pending: None,
            asked_at: None,
            asked_from: Vec3::zeros(),
            done_since: None,
            anchor: (Vec3::zeros(), Duration::ZERO),
            give_up: None,
            frontiers: 0,
            allocations: 0,
            given_up: 0,
            started_at: Duration::ZERO,
            crumbs: Vec::new(),
            clockwise: false,
            tracking: TrackingMargin::default(),
            hover_at: None,
            watch: blocked::PathWatch::default(),
            probing: None,
            boxed_since: None,
            left_within_room: None,
            kept_for_peer_at: None,
        }
    }

    /// Time for the beams to sweep all around once (four beams: a quarter turn).
    fn sense_s(&self) -> f64 {
        if self.goal.spin_rate > 0.0 {
            std::f64::consts::FRAC_PI_2 / self.goal.spin_rate
        } else {
            3.0
        }
    }

    /// The reference with this drone's heading: a steady turn (`spin`), or (`align`) a beam
    /// axis turned onto the direction of travel at up to `spin_rate`, turning steadily while
    /// slower than 0.3 m/s.
    fn heading(&self, ctx: &BehaviorContext, reference: MotionReference) -> MotionReference {
        if self.goal.spin_rate <= 0.0 {
            return reference;
        }
        let rate = self.goal.spin_rate;
        let v = ctx.state.velocity_enu_mps.xy();
        let yaw = match self.goal.heading {
            HeadingMode::Align if v.norm() > 0.3 => {
                let quarter = std::f64::consts::FRAC_PI_2;
                let error = crate::types::wrap_angle_rad(v.y.atan2(v.x) - ctx.yaw());
                // The nearest beam axis: the error folded into -pi/4..pi/4.
                let folded = error - quarter * (error / quarter).round();
                YawTarget::Rate((2.0 * folded).clamp(-rate, rate))
            }
            _ if self.clockwise => YawTarget::Rate(-rate),
            _ => YawTarget::Rate(rate),
        };
        with_yaw(reference, yaw)
    }

    /// Follows how far the drone strays across its path; says so when that widens the room
    /// the explorer keeps.
    fn watch_tracking(&mut self, ctx: &BehaviorContext, reference: Option<&MotionReference>) {
        let (point, velocity) = match reference {
            Some(MotionReference::Trajectory {
                position_enu_m,
                velocity_enu_mps,
                ..
            }) => (*position_enu_m, *velocity_enu_mps),
            Some(MotionReference::Position {
                position_enu_m,
                velocity_ff_enu_mps,
                ..
            }) => (*position_enu_m, *velocity_ff_enu_mps),
            _ => return,
        };
        if ctx.safety_override == Some(OverrideKind::Separation) {
            self.kept_for_peer_at = Some(ctx.now);
        }
        if self
            .kept_for_peer_at
            .is_some_and(|t| seconds(ctx.now, t) < PEER_GRACE_S)
        {
            self.tracking.excuse();
            return;
        }
        let before = self.tracking.extra_m();
        self.tracking.observe(
            point,
            velocity,
            ctx.position(),
            ctx.state.velocity_enu_mps,
            ctx.dt_s,
        );
        let after = self.tracking.extra_m();
        if after > before {
            tracing::warn!(
                "{}: strays up to {:.2} m from its path: exploring {:.1} m farther from obstacles \
                 and unknown space (safety_distance {:.2} m + {after:.1} m)",
                ctx.drone_id,
                self.tracking.peak_m(),
                after,
                self.goal.safety_distance
            );
        }
    }

    fn start_exploring(&mut self, ctx: &BehaviorContext) {
        self.base_z = ctx
            .home_enu_m
            .map_or(ctx.position().z, |h| h.z + self.goal.height);
        self.phase = Phase::Exploring;
        self.anchor = (ctx.position(), ctx.now);
        self.started_at = ctx.now;
    }

    /// Whether to ask the allocator now: with no goal, every `retarget_period`, and when the
    /// goal is near (so the next one is known before the drone stops).
    fn due_to_ask(&self, ctx: &BehaviorContext) -> bool {
        let since_asked = self.asked_at.map_or(f64::INFINITY, |t| seconds(ctx.now, t));
        let near_goal = self
            .target
            .is_some_and(|t| (t - ctx.position()).xy().norm() < NEAR_GOAL_M);
        self.pending.is_none()
            && since_asked >= MIN_ASK_INTERVAL.as_secs_f64()
            && (self.child.is_none() || near_goal || since_asked >= self.goal.retarget_period)
    }

    fn fly(&mut self, ctx: &BehaviorContext, goal: Vec3, path: &[Vec3]) -> Result<(), Failure> {
        let follow = self.path_goal(ctx, path);
        follow.check()?;
        let mut child = FollowPath::new(follow);
        child.activate(ctx).map_err(|e| e.within("follow_path"))?;
        self.child = Some(Box::new(child));
        self.target = Some(goal);
        self.watch.follow(ctx.position(), path);
        self.allocations += 1;
        Ok(())
    }

    /// A path flown at the cruise speed ([`ExploreGoal::cruise_mps`]). The heading is the
    /// explorer's own turn ([`Self::heading`]), so the path asks for none: one held at its start would keep the
    /// path from ending until the turn came round to it (up to a full turn, 42 s at the
    /// thesis's rate), which held drones over their landing spots at the end of a run.
    fn path_goal(&self, ctx: &BehaviorContext, path: &[Vec3]) -> FollowPathGoal {
        FollowPathGoal {
            path: path.iter().map(|p| [p.x, p.y, p.z]).collect(),
            speed: self.goal.cruise_mps(ctx.estimate_drift_mps),
            yaw: YawArgs {
                yaw_mode: YawMode::PathFacing,
                ..YawArgs::default()
            },
            frame_id: Some(EARTH.to_string()),
        }
    }

    /// Gives the goal up when the drone has stayed in one place for a full sweep with it. Time
    /// the safety stage holds it for a silent peer does not count: the goal is not what stops it.
    fn check_stuck(&mut self, ctx: &BehaviorContext) {
        let here = ctx.position();
        if (here - self.anchor.0).norm() > STUCK_RADIUS_M || lost_peer(ctx).is_some() {
            self.anchor = (here, ctx.now);
            return;
        }
        if seconds(ctx.now, self.anchor.1) > self.sense_s() + STUCK_EXTRA_S {
            if let Some(t) = self.target.take() {
                trace(ctx, "giveup", String::new);
                self.give_up = Some(t.xy());
                self.given_up += 1;
                self.child = None;
            }
            self.anchor = (here, ctx.now);
        }
    }

    fn explore_tick(
        &mut self,
        ctx: &BehaviorContext,
        requests: &mut Vec<PlatformRequest>,
    ) -> Result<Option<MotionReference>, Failure> {
        if self.must_give_way(ctx) {
            trace(ctx, "giveway", String::new);
            self.hover_at = None;
            self.phase = Phase::GivingWay {
                hold: Vec3::new(ctx.position().x, ctx.position().y, self.base_z),
                returning: false,
                since: ctx.now,
            };
            return Ok(Some(ctx.hold_here()));
        }
        if self.read_answer(ctx)? {
            if self.goal.land_when_done {
                self.go_land(ctx)?;
                return Ok(Some(ctx.hold_here()));
            }
            return Ok(None);
        }
        self.follow_map_step(ctx);
        self.drop_crumb(ctx);
        self.check_stuck(ctx);
        // Paths keep half the safety distance from obstacles unless they start closer: an
        // obstacle that near the path ahead was not on the map it was planned on.
        if self.child.is_some() && self.watch.blocked(ctx, 0.5 * self.goal.safety_distance) {
            trace(ctx, "blocked", String::new);
            self.child = None;
            self.watch.clear();
            self.asked_at = None;
        }
        if self.due_to_ask(ctx) {
            self.ask(ctx);
        }
        let Some(child) = self.child.as_mut() else {
            return Ok(Some(self.hover(ctx)));
        };
        match child.run(ctx, requests) {
            Step::Running {
                reference: Some(reference),
                ..
            } => {
                self.hover_at = None;
                Ok(Some(reference))
            }
            Step::Running {
                reference: None, ..
            } => Ok(Some(self.hover(ctx))),
            Step::Succeeded => {
                trace(ctx, "arrive", String::new);
                self.child = None;
                Ok(Some(self.hover(ctx)))
            }
            // Held for a silent peer: another frontier would be held the same way.
            Step::Failed(reason) if reason.code == FailureCode::FleetPeerLost => Err(reason),
            Step::Failed(reason) => {
                trace(ctx, "pathfail", String::new);
                tracing::debug!("{}: frontier path failed: {reason}", ctx.drone_id);
                self.give_up = self.target.take().map(|t| t.xy());
                self.child = None;
                Ok(Some(self.hover(ctx)))
            }
        }
    }

    /// After a map correction's step, the point it hovers on moves with it (the vehicle stays
    /// where it is), and a step of [`MAP_STEP_M`] or more drops the path and asks again from
    /// where the map now has the drone.
    fn follow_map_step(&mut self, ctx: &BehaviorContext) {
        let step = Vec3::new(ctx.map_step_m.x, ctx.map_step_m.y, 0.0);
        if step.norm() == 0.0 {
            return;
        }
        if let Some(at) = self.hover_at.as_mut() {
            *at += step;
        }
        if step.norm() >= MAP_STEP_M && self.child.is_some() {
            trace(ctx, "mapstep", || format!("{:.2}", step.norm()));
            self.child = None;
            self.watch.clear();
            self.asked_at = None;
            self.hover_at = Some(ctx.position());
        }
    }

    /// Hovers where the drone stopped, holding that point: a reference at wherever the drone
    /// is now would let the autopilot's own drift carry it off (on PX4 SIH, 2.4 m into a wall
    /// in 8 s while it sensed).
    fn hover(&mut self, ctx: &BehaviorContext) -> MotionReference {
        let at = *self.hover_at.get_or_insert_with(|| ctx.position());
        MotionReference::hold(at, ctx.yaw(), ctx.config.hold_speed_mps)
    }

    fn feedback(&self) -> serde_json::Value {
        let phase = match self.phase {
            Phase::TakingOff(_) => "takeoff",
            Phase::Exploring if self.done_since.is_some() => "sensing",
            Phase::Exploring => "navigating",
            Phase::GivingWay { .. } => "drone_avoidance",
            Phase::Relocating(_) | Phase::Landing(_) => "end",
        };
        json!({
            "phase": phase,
            "goal": self.target.map(|t| [t.x, t.y, t.z]),
            "frontiers": self.frontiers,
            "allocations": self.allocations,
            "given_up": self.given_up,
            "tracking_margin_m": self.tracking.extra_m(),
            "frontiers_left_within_room": self.left_within_room,
        })
    }
}

/// A debug line per explorer event (`RUST_LOG=kestrel::behavior::explore=debug`), read by
/// `benches/explore_stops.py` to tell where a drone stops and why.
fn trace(ctx: &BehaviorContext, event: &str, detail: impl FnOnce() -> String) {
    if tracing::enabled!(tracing::Level::DEBUG) {
        tracing::debug!(
            "EXTRACE t={:.2} d={} ev={event} {}",
            ctx.now.as_secs_f64(),
            ctx.drone_id,
            detail()
        );
    }
}

fn seconds(now: Duration, since: Duration) -> f64 {
    now.saturating_sub(since).as_secs_f64()
}

impl Behavior for Explore {
    fn activate(&mut self, ctx: &BehaviorContext) -> Result<(), Failure> {
        if ctx.is_flying() {
            self.start_exploring(ctx);
            return Ok(());
        }
        let mut takeoff = Takeoff::new(TakeoffGoal {
            height: self.goal.height,
            speed: 0.5,
        });
        takeoff.activate(ctx).map_err(|e| e.within("takeoff"))?;
        self.phase = Phase::TakingOff(Box::new(takeoff));
        Ok(())
    }

    fn run(&mut self, ctx: &BehaviorContext, requests: &mut Vec<PlatformRequest>) -> Step {
        let reference = match &mut self.phase {
            Phase::TakingOff(takeoff) => match takeoff.run(ctx, requests) {
                Step::Running { reference, .. } => reference,
                Step::Succeeded => {
                    self.start_exploring(ctx);
                    Some(self.heading(ctx, ctx.hold_here()))
                }
                Step::Failed(reason) => return Step::Failed(reason.within("takeoff")),
            },
            Phase::Relocating(child) => match child.run(ctx, requests) {
                Step::Running { reference, .. } => reference.map(|r| self.heading(ctx, r)),
                Step::Succeeded | Step::Failed(_) => {
                    // Clear now, or as clear as its track allows: land (the watcher and the
                    // safety stage still keep flying drones apart).
                    if let Err(e) = self.land_here(ctx) {
                        return Step::Failed(e);
                    }
                    Some(ctx.hold_here())
                }
            },
            Phase::Landing(land) => match land.run(ctx, requests) {
                Step::Running { reference, .. } => reference,
                Step::Succeeded => return Step::Succeeded,
                Step::Failed(reason) => return Step::Failed(reason.within("land")),
            },
            Phase::GivingWay {
                hold,
                returning,
                since,
            } => {
                let (hold, returning, since) = (*hold, *returning, *since);
                Some(self.give_way_tick(ctx, hold, returning, since))
            }
            Phase::Exploring => match self.explore_tick(ctx, requests) {
                Err(reason) => return Step::Failed(reason),
                Ok(None) => return Step::Succeeded,
                Ok(Some(reference)) => Some(self.heading(ctx, reference)),
            },
        };
        // The goal's speed holds for the holds borrowed from the context too (their
        // `hold_speed_mps` is faster): a hold that a map correction's step moved a metre off
        // flew back at 1 m/s.
        let cruise_mps = self.goal.cruise_mps(ctx.estimate_drift_mps);
        let reference = reference.map(|r| r.at_most(cruise_mps));
        if ctx.is_flying() {
            self.watch_tracking(ctx, reference.as_ref());
        }
        Step::Running {
            reference,
            feedback: self.feedback(),
        }
    }

    fn resume(&mut self, ctx: &BehaviorContext) {
        // Paused, it may have been flown elsewhere: it hovers where it is now.
        self.hover_at = None;
        if let Some(c) = self.child.as_mut() {
            c.resume(ctx);
        }
        self.anchor = (ctx.position(), ctx.now);
    }

    fn goal_enu_m(&self) -> Option<Vec3> {
        self.target
    }
}
