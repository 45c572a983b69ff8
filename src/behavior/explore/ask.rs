//! The explorer's questions to the fleet's frontier allocator and what it does with the
//! answers: a goal is flown (unless the drone has moved on since it asked), `Done` goes to the
//! end rule ([`super::end`]). Before an end with frontiers left while the drone keeps extra
//! room for straying, one more question without that room (claiming nothing) tells whether
//! frontiers were left only within it. A drone whose estimate drifts and that holds its path
//! again (at once or within [`BOXED_WAIT_S`] of hovering) then lets the room go and explores on
//! (it earns the room back by straying); one that still strays, or whose estimate does not
//! drift (its hold wanders: the room is what keeps it off the obstacles), ends and says so.
use super::end::{self, EndFacts, Left};
use super::{seconds, trace, Explore};
use crate::behavior::progress::lost_peer;
use crate::behavior::{BehaviorContext, Failure, FailureCode};
use crate::exploration::online::reach::KeepOut;
use crate::exploration::online::service::{Allocation, ExploreError, ExploreRequest};
use crate::exploration::online::space::SpaceParams;

/// An allocation is flown only if the drone is still this close to where it asked (m).
const STALE_ANSWER_M: f64 = 0.3;
/// Kept from a silent drone's last position beyond its uncertainty (m): the safety stage's
/// default least separation and its margin (1.0 + 0.2 m), and 0.3 m of room.
const SILENT_KEEP_OUT_M: f64 = 1.5;
/// A drone boxed in by its straying room waits this long for its stray to settle (s): a map
/// correction's jump of 0.8 m settles in about 12 s ([`TrackingMargin::holds_path`]).
///
/// [`TrackingMargin::holds_path`]: crate::exploration::online::tracking::TrackingMargin::holds_path
const BOXED_WAIT_S: f64 = 30.0;

impl Explore {
    /// Asks the allocator for a goal from where the drone is, with this drone's settings
    /// (the config's, with the goal's own over them) and what it gives up.
    pub(super) fn ask(&mut self, ctx: &BehaviorContext) {
        self.ask_keeping(ctx, self.tracking.extra_m(), true);
    }

    /// [`Self::ask`] with `extra_m` of room beyond the goal's safety distance; `claim`: the goal
    /// given is to be flown (others leave it).
    fn ask_keeping(&mut self, ctx: &BehaviorContext, extra_m: f64, claim: bool) {
        let settings = ctx.exploration.with(&self.goal.settings);
        let resolution_m = ctx.map.map_or(0.1, |m| m.grid().spec().resolution_m);
        let cells = |length_m: f64| ((length_m / resolution_m).round() as usize).max(1);
        let space = SpaceParams {
            safety_distance_m: self.goal.safety_distance + extra_m,
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
        let safety_distance_m = space.safety_distance_m;
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
            claim,
        }));
        self.asked_at = Some(ctx.now);
        self.asked_from = ctx.position();
        trace(ctx, "ask", || format!("safety={safety_distance_m:.2}"));
    }

    /// Takes the allocator's answer; `Ok(true)` when the exploration is over for this drone.
    pub(super) fn read_answer(&mut self, ctx: &BehaviorContext) -> Result<bool, Failure> {
        let Some(ticket) = self.pending.as_ref() else {
            return Ok(false);
        };
        let Some(answer) = ctx.services.take_allocation(ticket) else {
            return Ok(false);
        };
        self.pending = None;
        if let Some(kept_m) = self.probing.take() {
            return self.read_probe(ctx, answer, kept_m);
        }
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
                // Held for a silent peer, it sees no more than where it hovers: an end then would
                // leave what that peer's silence hides. It waits for the hold to end.
                if lost_peer(ctx).is_some() {
                    self.done_since = None;
                    return Ok(false);
                }
                let since = *self.done_since.get_or_insert(ctx.now);
                let facts = EndFacts {
                    exploring_s: seconds(ctx.now, self.started_at),
                    done_for_s: seconds(ctx.now, since),
                    here_s: seconds(ctx.now, self.anchor.1),
                    sense_s: self.sense_s(),
                    flown: self.allocations > 0 && self.crumbs.len() > 1,
                };
                let left = Left {
                    frontiers,
                    held,
                    unreached,
                };
                let over = end::over(left, &facts);
                let kept_m = self.tracking.extra_m();
                if over && frontiers > 0 && kept_m > 0.0 {
                    // Before it ends: is anything left within the room kept for straying?
                    self.probing = Some(kept_m);
                    self.ask_keeping(ctx, 0.0, false);
                    return Ok(false);
                }
                Ok(over)
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
                self.boxed_since = None;
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

    /// The answer to the last question before the end, asked with no room for straying: a goal
    /// there means frontiers were left only within the room kept. A drone whose estimate drifts
    /// (`estimate_drift_mps` > 0, whose map correction's jumps read as straying) and that holds
    /// its path now lets the room go and asks again; one that strays still hovers and asks
    /// again, for up to [`BOXED_WAIT_S`]. A drone whose estimate does not drift strays because
    /// its hold wanders (a real autopilot's), so it keeps the room. Else the exploration ends (the room is kept: with it,
    /// nothing is reachable), and says so (a warning, and `frontiers_left_within_room` in its
    /// feedback while it lands).
    fn read_probe(
        &mut self,
        ctx: &BehaviorContext,
        answer: Result<Allocation, ExploreError>,
        kept_m: f64,
    ) -> Result<bool, Failure> {
        let drifts = ctx.estimate_drift_mps > 0.0;
        match answer {
            Err(e) => Err(Failure::new(FailureCode::Internal, e.to_string())),
            Ok(Allocation::Done { .. }) => Ok(true),
            Ok(Allocation::Goal { frontiers, .. }) if drifts && self.tracking.holds_path() => {
                tracing::warn!(
                    "{}: {frontiers} frontier(s) left only within the {kept_m:.1} m kept for \
                     straying up to {:.2} m; it holds its path again, so it lets that room go \
                     and explores on",
                    ctx.drone_id,
                    self.tracking.peak_m()
                );
                trace(ctx, "relax", || format!("kept={kept_m:.1}"));
                self.tracking.relax();
                self.done_since = None;
                self.boxed_since = None;
                Ok(false)
            }
            Ok(Allocation::Goal { .. })
                if drifts
                    && seconds(ctx.now, *self.boxed_since.get_or_insert(ctx.now))
                        < BOXED_WAIT_S =>
            {
                trace(ctx, "boxed", || format!("kept={kept_m:.1}"));
                Ok(false)
            }
            Ok(Allocation::Goal { frontiers, .. }) => {
                let why = format!(
                    "exploration ends with {frontiers} frontier(s) left that it could reach \
                     only within the {kept_m:.1} m it kept beyond safety_distance {:.2} m for \
                     straying up to {:.2} m from its path (a drifting or wandering position \
                     estimate)",
                    self.goal.safety_distance,
                    self.tracking.peak_m()
                );
                tracing::warn!("{}: {why}", ctx.drone_id);
                trace(ctx, "short", || format!("kept={kept_m:.1}"));
                self.left_within_room = Some(frontiers);
                Ok(true)
            }
        }
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
