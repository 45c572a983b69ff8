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
//! begins, and the known space grows in bands about a beam range wide.
//!
//! The drone asks the fleet's frontier allocator (a service: asked on one tick, answered on a
//! later one) for a goal and the path to it through space observed free with the safety
//! distance all around (plus how far this drone has lately strayed across its path,
//! `exploration::tracking`, so an autopilot whose own hold wanders is kept that much farther
//! away), so it never flies where it has not seen; it asks again every
//! `retarget_period` s and whenever it arrives, so it re-targets without stopping. A frontier
//! it sat next to for a quarter turn without it going away is given up (an occluded pocket).
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

use super::follow_path::{FollowPath, FollowPathGoal};
use super::goal::{check_positive, check_within, GoalError, YawArgs, YawMode};
use super::land::{Land, LandGoal};
use super::navigate_to::with_yaw;
use super::registry::{BehaviorSpec, Goal, Resource};
use super::services::Ticket;
use super::takeoff::{Takeoff, TakeoffGoal};
use super::{Behavior, BehaviorContext, Failure, FailureCode, Step};
use crate::control::{MotionReference, YawTarget};
use crate::estimator::frames::EARTH;
use crate::exploration::allocation::AllocatorKind;
use crate::exploration::reach::KeepOut;
use crate::exploration::service::{Allocation, ExploreRequest, CLAIM_TTL};
use crate::exploration::settings::SettingsOverride;
use crate::exploration::space::SpaceParams;
use crate::exploration::tracking::TrackingMargin;
use crate::exploration::watcher::{may_return, must_yield, WatchParams, Watched};
use crate::mapping::grid::OccupancyGrid;
use crate::types::{PlatformRequest, Vec3};
use nalgebra::Vector2;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};
use serde_json::json;
use std::time::Duration;

/// Every field has the thesis's simulation value as its default (Table 5.3).
#[derive(Debug, Clone, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct ExploreGoal {
    /// Flight height above the takeoff point (m).
    pub height: f64,
    /// Cruise speed (m/s).
    pub speed: f64,
    /// Steady turn while exploring (rad/s, 0..=2), so the beams sweep all around; 0 keeps the
    /// heading (then only a 360-beam sensor sees sideways).
    pub spin_rate: f64,
    /// Least distance from obstacles and from unobserved space (m).
    pub safety_distance: f64,
    /// Closer than this to another drone at the same height, one of the two gives way (m).
    pub drone_safety_distance: f64,
    /// Which frontier to take next.
    pub allocator: AllocatorKind,
    /// Ask the allocator again this often while flying to a frontier (s).
    pub retarget_period: f64,
    /// Land when no frontier is left.
    pub land_when_done: bool,
    /// How the heading moves: `spin` (a steady turn) or `align` (a beam axis along the travel).
    pub heading: HeadingMode,
    /// Frontiers shorter than this (m) are not flown to while longer ones are left (the
    /// thesis drops them: 1.5 m).
    pub min_frontier_length: f64,
    /// Frontiers shorter than this (m) are never flown to, unless at least half as long and
    /// leading on to a large unknown region (a gap between obstacles); between this and
    /// `min_frontier_length` they are explored last. Lower it (to 0.5 m) for a more thorough
    /// end at the cost of time.
    pub end_frontier_length: f64,
    /// Fly along frontiers of 2 m or more from end to end, turning the way that sweeps the
    /// unknown side best (the beams clear them on the way), instead of to their middle and
    /// waiting there for the turn to sweep them.
    pub sweep_along: bool,
    /// The exploration's weights for this drone (`edge_bonus_m`, `others_penalty_m`, ...):
    /// each field given replaces the config's `[exploration]` value; those left out keep it.
    pub settings: SettingsOverride,
}

/// How the explorer turns its beams.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum HeadingMode {
    /// A steady turn at `spin_rate`: the four beams sweep all around, all the time.
    #[default]
    Spin,
    /// A beam axis along the direction of travel (the side beams sweep the widest band); a
    /// steady turn while hovering.
    Align,
}

impl Default for ExploreGoal {
    fn default() -> Self {
        ExploreGoal {
            height: 1.0,
            speed: 0.75,
            spin_rate: 0.15,
            safety_distance: 0.4,
            drone_safety_distance: 2.0,
            allocator: AllocatorKind::default(),
            retarget_period: 2.0,
            land_when_done: true,
            heading: HeadingMode::default(),
            min_frontier_length: 1.5,
            end_frontier_length: 1.0,
            sweep_along: true,
            settings: SettingsOverride::default(),
        }
    }
}

impl Goal for ExploreGoal {
    fn check(&self) -> Result<(), GoalError> {
        check_within("height", self.height, 0.2, 100.0, "m")?;
        check_positive("speed", self.speed, "m/s")?;
        check_within("spin_rate", self.spin_rate, 0.0, 2.0, "rad/s")?;
        check_within("safety_distance", self.safety_distance, 0.1, 5.0, "m")?;
        check_within(
            "drone_safety_distance",
            self.drone_safety_distance,
            0.5,
            50.0,
            "m",
        )?;
        check_within("retarget_period", self.retarget_period, 0.2, 60.0, "s")?;
        check_within(
            "min_frontier_length",
            self.min_frontier_length,
            0.1,
            20.0,
            "m",
        )?;
        check_within(
            "end_frontier_length",
            self.end_frontier_length,
            0.1,
            self.min_frontier_length,
            "m (at most min_frontier_length)",
        )?;
        self.settings.validate().map_err(|e| GoalError::OutOfRange {
            name: format!("settings.{}", e.field),
            value: e.value,
            lo: e.min,
            hi: e.max,
            unit: e.unit.to_string(),
        })
    }
    fn speeds_mps(&self) -> Vec<f64> {
        vec![self.speed]
    }
}

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
/// Track points kept for finding a landing spot, and their spacing (m).
const MAX_CRUMBS: usize = 512;
const CRUMB_SPACING_M: f64 = 1.0;
/// A drone lands at least this far (horizontally) from every other drone (m).
const LANDING_CLEARANCE_M: f64 = 1.5;
/// Closer than this to its goal, a drone asks for the next one (m).
const NEAR_GOAL_M: f64 = 1.5;
/// An allocation is flown only if the drone is still this close to where it asked (m).
const STALE_ANSWER_M: f64 = 0.3;
/// With frontiers left that others hold, a drone waits this long past the claims' lifetime
/// before it ends (s): a failed drone's claims lapse and its frontiers are offered first.
const CLAIM_LAPSE_EXTRA_S: f64 = 2.0;
/// A drone that moved less than this ...
const STUCK_RADIUS_M: f64 = 1.0;
/// ... for a quarter turn plus this long gives its goal up.
const STUCK_EXTRA_S: f64 = 2.0;
/// A drone giving way counts as up after this long even short of the full climb (s; the climb
/// itself takes about 2 s).
const GIVE_WAY_CLIMB_LIMIT_S: f64 = 8.0;
/// Kept from a silent drone's last position beyond its uncertainty (m): the safety stage's
/// default least separation and its margin (1.0 + 0.2 m), and 0.3 m of room.
const SILENT_KEEP_OUT_M: f64 = 1.5;

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

    fn ask(&mut self, ctx: &BehaviorContext) {
        let settings = ctx.exploration.with(&self.goal.settings);
        let resolution_m = ctx.map.map_or(0.1, |m| m.grid().spec().resolution_m);
        let cells = |length_m: f64| ((length_m / resolution_m).round() as usize).max(1);
        let space = SpaceParams {
            safety_distance_m: self.goal.safety_distance + self.tracking.extra_m(),
            min_cells: cells(self.goal.min_frontier_length),
            min_final_cells: cells(self.goal.end_frontier_length),
            min_gain_cells: (settings.pocket_area_m2 / (resolution_m * resolution_m)).round()
                as usize,
            gain_cap_cells: (settings.worth_any_trip_m2 / (resolution_m * resolution_m)).round()
                as usize,
            occupied_threshold: ctx
                .map
                .map_or(SpaceParams::default().occupied_threshold, |m| {
                    m.occupied_threshold()
                }),
            ..SpaceParams::default()
        };
        self.pending = Some(ctx.services.explore(ExploreRequest {
            drone: ctx.drone_id.into(),
            position_enu_m: ctx.position(),
            flight_height_m: self.base_z,
            allocator: self.goal.allocator,
            settings,
            space,
            current_goal_enu_m: self.target.map(|t| t.xy()),
            give_up: self.give_up.take(),
            sweep_along: self.goal.sweep_along,
            keep_out: silent_keep_out(ctx),
        }));
        self.asked_at = Some(ctx.now);
        self.asked_from = ctx.position();
        trace(ctx, "ask", String::new);
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

    /// Takes the allocator's answer; `Ok(true)` when the exploration is over for this drone.
    fn read_answer(&mut self, ctx: &BehaviorContext) -> Result<bool, Failure> {
        let Some(ticket) = self.pending.as_ref() else {
            return Ok(false);
        };
        let Some(answer) = ctx.services.take_allocation(ticket) else {
            return Ok(false);
        };
        self.pending = None;
        match answer {
            Err(e) => Err(Failure::new(FailureCode::Internal, e.to_string())),
            Ok(Allocation::Done {
                frontiers,
                held,
                unreached,
            }) => {
                trace(ctx, "done", || {
                    format!("frontiers={frontiers} held={held} unreached={unreached}")
                });
                self.frontiers = frontiers;
                self.target = None;
                self.child = None;
                // Nothing left anywhere after a full sweep, or, after a flight (it turns all
                // the time), only frontiers it can reach but that are not worth the trip: over.
                // Before its first flight (space may open up as it turns), with frontiers that
                // others hold, or with frontiers it has no path to from here (boxed in by
                // unknown space that sensing may open): a quarter turn, and long enough for the
                // claims of a drone that failed to lapse, so its part is taken.
                let swept = seconds(ctx.now, self.started_at) >= self.sense_s();
                let since = *self.done_since.get_or_insert(ctx.now);
                let wait_s = self
                    .sense_s()
                    .max(CLAIM_TTL.as_secs_f64() + CLAIM_LAPSE_EXTRA_S);
                // Having flown to a frontier, its beams swept all around on the way here. A goal
                // where it already hovers (given while the space round its start is still
                // opening up) is no flight: a metre or more of track is.
                let flown = self.allocations > 0 && self.crumbs.len() > 1;
                // Within a metre of here for a quarter turn: its beams swept all around from
                // here, so what it has no path to stays that way (while no one else explores).
                let stayed = seconds(ctx.now, self.anchor.1) >= self.sense_s();
                Ok((swept
                    && (frontiers == 0 || (held == 0 && flown && (unreached == 0 || stayed))))
                    || seconds(ctx.now, since) >= wait_s)
            }
            Ok(Allocation::Goal {
                goal_enu_m,
                path_enu_m,
                frontiers,
                clockwise,
            }) => {
                // A sweep says which way to turn; any other goal keeps the turn as it is.
                if let Some(clockwise) = clockwise {
                    self.clockwise = clockwise;
                }
                self.frontiers = frontiers;
                self.done_since = None;
                // A late answer (a slow allocator on the wall clock) has a path from where the
                // drone was, not where it is: the way back to its start may not be clear. Asked
                // again instead; the drone flies on meanwhile.
                if (ctx.position() - self.asked_from).xy().norm() > STALE_ANSWER_M {
                    return Ok(false);
                }
                let same = self
                    .target
                    .is_some_and(|t| (t - goal_enu_m).norm() < 0.3 && self.child.is_some());
                let (here, had_child) = (ctx.position(), self.child.is_some());
                trace(ctx, if same { "same" } else { "fly" }, || {
                    format!(
                        "goal={:.2},{:.2} dist={:.2} had_child={}",
                        goal_enu_m.x,
                        goal_enu_m.y,
                        (goal_enu_m - here).xy().norm(),
                        had_child
                    )
                });
                if !same {
                    self.fly(ctx, goal_enu_m, &path_enu_m)?;
                }
                Ok(false)
            }
        }
    }

    fn fly(&mut self, ctx: &BehaviorContext, goal: Vec3, path: &[Vec3]) -> Result<(), Failure> {
        let follow = self.path_goal(path);
        follow.check()?;
        let mut child = FollowPath::new(follow);
        child.activate(ctx).map_err(|e| e.within("follow_path"))?;
        self.child = Some(Box::new(child));
        self.target = Some(goal);
        self.allocations += 1;
        Ok(())
    }

    /// A path flown at the exploring speed. The heading is the explorer's own turn
    /// ([`Self::heading`]), so the path asks for none: one held at its start would keep the
    /// path from ending until the turn came round to it (up to a full turn, 42 s at the
    /// thesis's rate), which held drones over their landing spots at the end of a run.
    fn path_goal(&self, path: &[Vec3]) -> FollowPathGoal {
        FollowPathGoal {
            path: path.iter().map(|p| [p.x, p.y, p.z]).collect(),
            speed: self.goal.speed,
            yaw: YawArgs {
                yaw_mode: YawMode::PathFacing,
                ..YawArgs::default()
            },
            frame_id: Some(EARTH.to_string()),
        }
    }

    /// Gives the goal up when the drone has stayed in one place for a full sweep with it.
    fn check_stuck(&mut self, ctx: &BehaviorContext) {
        let here = ctx.position();
        if (here - self.anchor.0).norm() > STUCK_RADIUS_M {
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

    /// The watcher's view of this drone (`remaining_m` to its goal, `up` when giving way).
    fn watched_me<'a>(&self, ctx: &BehaviorContext<'a>, up: bool) -> Watched<'a> {
        let here = ctx.position();
        Watched {
            id: ctx.drone_id,
            position_enu_m: [here.x, here.y, here.z],
            remaining_m: self.target.map_or(0.0, |t| (t - here).xy().norm()),
            up,
        }
    }

    /// The watcher's view of the other flying drones.
    fn watched_others<'a>(&self, ctx: &BehaviorContext<'a>) -> Vec<Watched<'a>> {
        ctx.fleet
            .others(ctx.drone_id)
            // A silent remote drone cannot give way in turn: the safety stage keeps away from it.
            .filter(|d| d.flying && !d.silent)
            .map(|d| Watched {
                id: &d.id,
                position_enu_m: [d.position_enu_m.x, d.position_enu_m.y, d.position_enu_m.z],
                remaining_m: d
                    .goal_enu_m
                    .map_or(0.0, |g| (g - d.position_enu_m).xy().norm()),
                up: d.position_enu_m.z > self.base_z + 0.5,
            })
            .collect()
    }

    fn must_give_way(&self, ctx: &BehaviorContext) -> bool {
        let params = WatchParams::thesis(self.goal.drone_safety_distance);
        let me = self.watched_me(ctx, false);
        must_yield(&me, self.base_z, &self.watched_others(ctx), &params)
    }

    fn clear_to_return(&self, ctx: &BehaviorContext) -> bool {
        let params = WatchParams::thesis(self.goal.drone_safety_distance);
        let me = self.watched_me(ctx, true);
        may_return(&me, &self.watched_others(ctx), &params)
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
        self.drop_crumb(ctx);
        self.check_stuck(ctx);
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

    /// Hovers where the drone stopped, holding that point: a reference at wherever the drone
    /// is now would let the autopilot's own drift carry it off (on PX4 SIH, 2.4 m into a wall
    /// in 8 s while it sensed).
    fn hover(&mut self, ctx: &BehaviorContext) -> MotionReference {
        let at = *self.hover_at.get_or_insert_with(|| ctx.position());
        MotionReference::hold(at, ctx.yaw(), ctx.config.hold_speed_mps)
    }

    /// Remembers where the drone flew (every `CRUMB_SPACING_M`), to find a landing spot.
    fn drop_crumb(&mut self, ctx: &BehaviorContext) {
        let here = Vec3::new(ctx.position().x, ctx.position().y, self.base_z);
        if self
            .crumbs
            .last()
            .is_none_or(|c| (c - here).norm() >= CRUMB_SPACING_M)
        {
            if self.crumbs.len() >= MAX_CRUMBS {
                self.crumbs.remove(0);
            }
            self.crumbs.push(here);
        }
    }

    /// Lands here, or first flies back along its own track to the last point clear of every
    /// other drone (flying at its height or lower, or landed) when one is closer than
    /// `LANDING_CLEARANCE_M`: a drone never lands on another.
    fn go_land(&mut self, ctx: &BehaviorContext) -> Result<(), Failure> {
        // The autopilot's own landing drifts as its hold does: as far from obstacles as the
        // drone explored.
        let obstacle_clearance_m = self.goal.safety_distance + self.tracking.extra_m();
        // Drones out of the way above (giving way) are no reason to move: this one descends
        // away from them.
        let clear = |p: &Vec3| {
            ctx.fleet.others(ctx.drone_id).all(|d| {
                (d.position_enu_m - p).xy().norm() > LANDING_CLEARANCE_M
                    || d.position_enu_m.z > p.z + 0.5
            }) && ctx.map.is_none_or(|m| {
                no_obstacle_within(m.grid(), m.occupied_threshold(), p, obstacle_clearance_m)
            })
        };
        if clear(&ctx.position()) {
            let mut land = Land::new(LandGoal { speed: 0.5 });
            land.activate(ctx).map_err(|e| e.within("land"))?;
            self.phase = Phase::Landing(Box::new(land));
            return Ok(());
        }
        let back: Vec<Vec3> = match self.crumbs.iter().rposition(clear) {
            Some(k) => self.crumbs[k..].iter().rev().copied().collect(),
            None => self.crumbs.iter().rev().copied().collect(),
        };
        if back.is_empty() {
            return Err(Failure::new(
                FailureCode::Internal,
                "no clear place to land: another drone is below",
            ));
        }
        let follow = self.path_goal(&back);
        let mut child = FollowPath::new(follow);
        child.activate(ctx).map_err(|e| e.within("follow_path"))?;
        self.phase = Phase::Relocating(Box::new(child));
        Ok(())
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

/// Whether no cell of `grid` within `radius_m` of `p` (horizontally) is an obstacle.
fn no_obstacle_within(grid: &OccupancyGrid, occupied: i8, p: &Vec3, radius_m: f64) -> bool {
    let resolution_m = grid.spec().resolution_m;
    let n = (radius_m / resolution_m).ceil() as i64;
    (-n..=n).all(|dy| {
        (-n..=n).all(|dx| {
            let offset = Vector2::new(dx as f64, dy as f64) * resolution_m;
            offset.norm() > radius_m
                || grid
                    .get_at(p.xy() + offset)
                    .is_none_or(|value| value < occupied)
        })
    })
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
                    let mut land = Land::new(LandGoal { speed: 0.5 });
                    if let Err(e) = land.activate(ctx) {
                        return Step::Failed(e.within("land"));
                    }
                    self.phase = Phase::Landing(Box::new(land));
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
                let (hold, was_returning, since) = (*hold, *returning, *since);
                let up = Vec3::new(hold.x, hold.y, hold.z + 1.0);
                let here = ctx.position();
                // Up, or as far up as it gets: a drone already giving way right above it keeps
                // the safety stage from letting it climb the whole metre, and that drone waits
                // for this one to leave.
                let climbed = (here.z - up.z).abs() < 0.15
                    || seconds(ctx.now, since) >= GIVE_WAY_CLIMB_LIMIT_S;
                let returning = was_returning || (climbed && self.clear_to_return(ctx));
                self.phase = Phase::GivingWay {
                    hold,
                    returning,
                    since,
                };
                let target = if returning { hold } else { up };
                if returning && (here - hold).norm() < 0.15 {
                    self.phase = Phase::Exploring;
                    if let Some(c) = self.child.as_mut() {
                        c.resume(ctx);
                    }
                    self.anchor = (here, ctx.now);
                }
                Some(self.heading(
                    ctx,
                    MotionReference::hold(target, ctx.yaw(), ctx.config.hold_speed_mps.min(0.5)),
                ))
            }
            Phase::Exploring => match self.explore_tick(ctx, requests) {
                Err(reason) => return Step::Failed(reason),
                Ok(None) => return Step::Succeeded,
                Ok(Some(reference)) => Some(self.heading(ctx, reference)),
            },
        };
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

/// Around each drone another Kestrel flew that fell silent: where it could be (its
/// uncertainty) plus what the safety stage keeps from it, and room to turn there. The
/// allocator neither sends a drone into these discs nor routes through them; the safety stage
/// would stop it at their edge, and the frontier would hold it there.
fn silent_keep_out(ctx: &BehaviorContext) -> Vec<KeepOut> {
    ctx.fleet
        .drones
        .iter()
        .filter(|d| d.silent && !d.local && &*d.id != ctx.drone_id)
        .map(|d| KeepOut {
            centre_enu_m: d.position_enu_m.xy(),
            radius_m: d.uncertainty_m + SILENT_KEEP_OUT_M,
        })
        .collect()
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use crate::behavior::services::{ServiceAnswer, ServiceCall};
    use crate::behavior::testing::Scene;

    /// The explorer's question this tick, answered with a goal 5 m east of where it asked.
    fn answer_with_goal(scene: &Scene) {
        let calls = scene.services.drain_calls();
        let Some(ServiceCall::Explore(job)) = calls.into_iter().next() else {
            panic!("no question to the allocator");
        };
        let from = job.request.position_enu_m;
        let goal = from + Vec3::new(5.0, 0.0, 0.0);
        let answer = Allocation::Goal {
            goal_enu_m: goal,
            path_enu_m: vec![from, goal],
            frontiers: 1,
            clockwise: None,
        };
        scene
            .services
            .deliver(job.ticket, ServiceAnswer::Explore(Ok(answer)), job.cancel);
    }

    /// The explorer's question this tick, answered `Done`.
    fn answer_done(scene: &Scene, frontiers: usize, held: usize, unreached: usize) {
        let calls = scene.services.drain_calls();
        let Some(ServiceCall::Explore(job)) = calls.into_iter().next() else {
            panic!("no question to the allocator");
        };
        let answer = Allocation::Done {
            frontiers,
            held,
            unreached,
        };
        scene
            .services
            .deliver(job.ticket, ServiceAnswer::Explore(Ok(answer)), job.cancel);
    }

    fn other(x: f64, z: f64) -> crate::types::DroneView {
        crate::types::DroneView::at_rest("other", Vec3::new(x, 0.0, z), z > 0.1)
    }

    #[test]
    fn a_drone_lands_beside_one_giving_way_above_but_moves_away_from_one_level_or_landed() {
        let landing_from = |other_drone: crate::types::DroneView| {
            let mut scene = Scene::flying();
            scene.fleet.drones.push(other_drone);
            let mut explore = Explore::new(ExploreGoal::default());
            // It came from 3 m west, along its track.
            for x in [-3.0, -2.0, -1.0, 0.0] {
                scene.set_position(Vec3::new(x, 0.0, 1.0), Vec3::zeros());
                explore.drop_crumb(&scene.ctx(0));
            }
            explore.start_exploring(&scene.ctx(0));
            explore.go_land(&scene.ctx(1)).unwrap();
            explore.phase
        };
        // 1 m aside and 1 m up (giving way): it descends away from it, here.
        assert!(matches!(landing_from(other(1.0, 2.0)), Phase::Landing(_)));
        // Level with it, or landed there: back along its track first.
        assert!(matches!(
            landing_from(other(1.0, 1.0)),
            Phase::Relocating(_)
        ));
        assert!(matches!(
            landing_from(other(1.0, 0.0)),
            Phase::Relocating(_)
        ));
    }

    #[test]
    fn a_landing_spot_is_as_far_from_obstacles_as_the_drone_explored() {
        use crate::mapping::grid::GridSpec;
        let spec = GridSpec {
            resolution_m: 0.1,
            width_cells: 40,
            height_cells: 40,
            origin_enu_m: Vector2::zeros(),
        };
        let mut grid = OccupancyGrid::new(spec).unwrap();
        // One obstacle cell at (2.05, 2.05).
        grid.set(crate::mapping::grid::Cell { x: 20, y: 20 }, 100)
            .unwrap();
        let at = |x: f64| Vec3::new(x, 2.05, 0.0);
        assert!(!no_obstacle_within(&grid, 50, &at(2.5), 0.5), "0.45 m off");
        assert!(no_obstacle_within(&grid, 50, &at(2.7), 0.5), "0.65 m off");
        assert!(
            no_obstacle_within(&grid, 101, &at(2.5), 0.5),
            "below the threshold"
        );
    }

    #[test]
    fn a_drone_sensing_where_it_stopped_holds_that_point_against_drift() {
        let mut scene = Scene::flying();
        scene.set_position(Vec3::new(1.0, 2.0, 1.0), Vec3::zeros());
        let mut explore = Explore::new(ExploreGoal::default());
        explore.start_exploring(&scene.ctx(0));
        let mut requests = Vec::new();
        let point = |r: Option<MotionReference>| match r {
            Some(MotionReference::Position { position_enu_m, .. }) => position_enu_m,
            other => panic!("expected a hold, got {other:?}"),
        };
        let first = point(explore.explore_tick(&scene.ctx(1), &mut requests).unwrap());
        // The autopilot's own drift carries it 0.5 m north: the hold stays where it stopped.
        scene.set_position(Vec3::new(1.0, 2.5, 1.0), Vec3::new(0.0, 0.3, 0.0));
        let later = point(explore.explore_tick(&scene.ctx(2), &mut requests).unwrap());
        assert!((first - Vec3::new(1.0, 2.0, 1.0)).norm() < 1e-9, "{first}");
        assert_eq!(later, first);
        // Paused and flown elsewhere, it hovers where it is then.
        explore.resume(&scene.ctx(3));
        let resumed = point(explore.explore_tick(&scene.ctx(3), &mut requests).unwrap());
        assert!(
            (resumed - Vec3::new(1.0, 2.5, 1.0)).norm() < 1e-9,
            "{resumed}"
        );
    }

    #[test]
    fn a_drone_giving_way_under_another_that_gave_way_comes_back_once_the_level_one_has_gone() {
        // It flew in under a drone already up out of the way; now a level drone with farther
        // to go comes within 2 m, so it gives way too, but the drone above keeps it at 1.35 m.
        let mut scene = Scene::flying();
        scene.set_position(Vec3::new(0.0, 0.0, 1.0), Vec3::zeros());
        let mut level = other(1.5, 1.0);
        level.id = "drone_1".into();
        level.goal_enu_m = Some(Vec3::new(20.0, 0.0, 1.0));
        let mut above = other(0.1, 2.0);
        above.id = "drone_3".into();
        scene.fleet.drones = vec![level, above];
        let mut explore = Explore::new(ExploreGoal::default());
        explore.start_exploring(&scene.ctx(0));
        let mut requests = Vec::new();
        explore.run(&scene.ctx(1), &mut requests);
        assert!(matches!(explore.phase, Phase::GivingWay { .. }));
        scene.set_position(Vec3::new(0.0, 0.0, 1.35), Vec3::zeros());
        // The level drone goes on; the one above waits for this one to leave.
        scene.fleet.drones.remove(0);
        let returning = |e: &Explore| {
            matches!(
                e.phase,
                Phase::GivingWay {
                    returning: true,
                    ..
                }
            )
        };
        explore.run(&scene.ctx(3), &mut requests);
        assert!(!returning(&explore), "still climbing");
        explore.run(&scene.ctx(10), &mut requests);
        assert!(
            returning(&explore),
            "as far up as it gets, and clear: back down"
        );
    }

    #[test]
    fn a_late_answer_from_where_the_drone_no_longer_is_is_asked_again_not_flown() {
        let mut scene = Scene::flying();
        scene.set_position(Vec3::new(0.0, 0.0, 1.0), Vec3::zeros());
        let mut explore = Explore::new(ExploreGoal::default());
        explore.start_exploring(&scene.ctx(0));
        let mut requests = Vec::new();
        explore.explore_tick(&scene.ctx(1), &mut requests).unwrap();
        // The answer comes once the drone has drifted 1 m: its path starts where it was.
        scene.set_position(Vec3::new(0.0, 1.0, 1.0), Vec3::zeros());
        answer_with_goal(&scene);
        explore.explore_tick(&scene.ctx(2), &mut requests).unwrap();
        assert!(explore.target.is_none() && explore.child.is_none());
        // It asked again from here; an answer from here is flown.
        answer_with_goal(&scene);
        explore.explore_tick(&scene.ctx(3), &mut requests).unwrap();
        assert_eq!(explore.target, Some(Vec3::new(5.0, 1.0, 1.0)));
        assert!(explore.child.is_some());
    }

    #[test]
    fn with_nothing_worth_a_trip_left_a_drone_ends_at_once_unless_others_hold_frontiers() {
        // (frontiers left, held by others, without a path from here, flights so far) ->
        // whether the first answer ends the exploration.
        let ends_after = |here_s: u64, frontiers: usize, held: usize, unreached: usize, flown| {
            let scene = Scene::flying();
            let mut explore = Explore::new(ExploreGoal::default());
            explore.start_exploring(&scene.ctx(0));
            explore.allocations = flown;
            // A flight leaves a metre or more of track.
            if flown > 0 {
                explore.crumbs = vec![Vec3::zeros(), Vec3::new(1.5, 0.0, 0.0)];
            }
            // It came within a metre of where it is `here_s` ago.
            explore.anchor.1 = Duration::from_secs(12 - here_s);
            let mut requests = Vec::new();
            // After the first quarter turn (10.5 s at the thesis's rate).
            explore.explore_tick(&scene.ctx(11), &mut requests).unwrap();
            answer_done(&scene, frontiers, held, unreached);
            explore.explore_tick(&scene.ctx(12), &mut requests).unwrap();
            matches!(explore.phase, Phase::Landing(_) | Phase::Relocating(_))
        };
        let ends_at_once =
            |frontiers, held, unreached, flown| ends_after(1, frontiers, held, unreached, flown);
        assert!(ends_at_once(0, 0, 0, 0));
        // Left only frontiers it can reach but that are not worth its trip, after a flight to
        // a frontier: over. Before any (space may open up as it turns): it waits.
        assert!(ends_at_once(3, 0, 0, 1));
        assert!(!ends_at_once(3, 0, 0, 0));
        // Frontiers others hold: it waits (a failed drone's claims lapse, its part comes back).
        assert!(!ends_at_once(3, 1, 0, 1));
        // Frontiers it has no path to from here (boxed in by unknown space): it turns and
        // asks again instead of leaving a third of the world unexplored; once it has turned
        // a quarter turn where it is, sensing opens no more: over.
        assert!(!ends_at_once(3, 0, 2, 1));
        assert!(ends_after(11, 3, 0, 2, 1));
        assert!(
            !ends_after(11, 3, 1, 2, 1),
            "others hold frontiers: it waits"
        );
    }

    #[test]
    fn a_goal_where_the_drone_hovers_is_no_flight_for_the_end_rule() {
        // At its start, the space round the drone opens up as it turns: a goal given where it
        // hovers, then frontiers it has no path to yet, must not end its exploration.
        let scene = Scene::flying();
        let mut explore = Explore::new(ExploreGoal::default());
        explore.start_exploring(&scene.ctx(0));
        explore.allocations = 1;
        explore.crumbs = vec![Vec3::zeros()];
        explore.anchor.1 = Duration::ZERO;
        let mut requests = Vec::new();
        explore.explore_tick(&scene.ctx(11), &mut requests).unwrap();
        answer_done(&scene, 3, 0, 3);
        explore.explore_tick(&scene.ctx(12), &mut requests).unwrap();
        assert!(matches!(explore.phase, Phase::Exploring), "it waits");
    }
}
