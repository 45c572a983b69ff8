//! Drone avoidance, the explorer's side of it: when the watcher
//! ([`crate::exploration::online::watcher`]) says this drone gives way, it climbs 1 m above where it
//! was (or as far as it gets in 8 s) and holds there until the other drone has passed, then
//! comes back down and explores on.

use super::{seconds, Explore, Phase};
use crate::behavior::BehaviorContext;
use crate::control::MotionReference;
use crate::exploration::online::watcher::{may_return, must_yield, WatchParams, Watched};
use crate::types::Vec3;
use std::time::Duration;

/// A drone giving way counts as up after this long even short of the full climb (s; the climb
/// itself takes about 2 s).
const GIVE_WAY_CLIMB_LIMIT_S: f64 = 8.0;

/// Whether a drone giving way is up: within 0.15 m of the height it climbs to (`up_z`), or,
/// after [`GIVE_WAY_CLIMB_LIMIT_S`], as far up as it gets.
fn climbed(here_z: f64, up_z: f64, giving_way_s: f64) -> bool {
    (here_z - up_z).abs() < 0.15 || giving_way_s >= GIVE_WAY_CLIMB_LIMIT_S
}

impl Explore {
    /// The watcher's view of this drone (`remaining_m` to its goal, `up` when giving way).
    fn watched_me<'a>(&self, ctx: &BehaviorContext<'a>, up: bool) -> Watched<'a> {
        let here = ctx.position();
        Watched {
            id: ctx.drone_id,
            position_enu_m: [here.x, here.y, here.z],
            remaining_m: self.target.map_or(0.0, |t| (t - here).xy().norm()),
            up,
            uncertainty_m: ctx.fleet.get(ctx.drone_id).map_or(0.0, |d| d.uncertainty_m),
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
                // A remote drone's is how far it flew since heard; only the drift counts here.
                uncertainty_m: if d.local { d.uncertainty_m } else { 0.0 },
            })
            .collect()
    }

    pub(super) fn must_give_way(&self, ctx: &BehaviorContext) -> bool {
        let params = WatchParams::thesis(self.goal.drone_safety_distance);
        let me = self.watched_me(ctx, false);
        must_yield(&me, self.base_z, &self.watched_others(ctx), &params)
    }

    fn clear_to_return(&self, ctx: &BehaviorContext) -> bool {
        let params = WatchParams::thesis(self.goal.drone_safety_distance);
        let me = self.watched_me(ctx, true);
        may_return(&me, &self.watched_others(ctx), &params)
    }

    /// One tick out of another drone's way, above `hold` since `since`: up, then (once clear)
    /// back down to `hold` and on exploring.
    pub(super) fn give_way_tick(
        &mut self,
        ctx: &BehaviorContext,
        hold: Vec3,
        was_returning: bool,
        since: Duration,
    ) -> MotionReference {
        let up = Vec3::new(hold.x, hold.y, hold.z + 1.0);
        let here = ctx.position();
        // Up, or as far up as it gets: a drone already giving way right above it keeps
        // the safety stage from letting it climb the whole metre, and that drone waits
        // for this one to leave.
        let is_up = climbed(here.z, up.z, seconds(ctx.now, since));
        let returning = was_returning || (is_up && self.clear_to_return(ctx));
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
        self.heading(
            ctx,
            MotionReference::hold(target, ctx.yaw(), ctx.config.hold_speed_mps.min(0.5)),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_drone_giving_way_is_up_at_the_height_or_after_the_climbs_time() {
        assert!(climbed(1.9, 2.0, 1.0));
        assert!(!climbed(1.8, 2.0, 7.9));
        assert!(climbed(1.35, 2.0, 8.0), "as far up as it gets");
    }
}
