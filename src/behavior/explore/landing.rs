//! The explorer's end in the air: where it lands. It keeps a track of where it flew (a point a
//! metre), and lands where it is unless another drone is too close; then back along that track
//! to the last point clear of the others (and as far from obstacles as it explored) first.

use super::{Explore, Phase};
use crate::behavior::follow_path::FollowPath;
use crate::behavior::land::{Land, LandGoal};
use crate::behavior::{Behavior, BehaviorContext, Failure, FailureCode};
use crate::mapping::grid::OccupancyGrid;
use crate::types::Vec3;
use nalgebra::Vector2;

/// Track points kept for finding a landing spot, and their spacing (m).
const MAX_CRUMBS: usize = 512;
const CRUMB_SPACING_M: f64 = 1.0;
/// A drone lands at least this far (horizontally) from every other drone (m).
const LANDING_CLEARANCE_M: f64 = 1.5;

/// Adds `here` to the track when it is [`CRUMB_SPACING_M`] or more from the last point, the
/// oldest dropped beyond [`MAX_CRUMBS`].
fn push_crumb(crumbs: &mut Vec<Vec3>, here: Vec3) {
    if crumbs
        .last()
        .is_none_or(|c| (c - here).norm() >= CRUMB_SPACING_M)
    {
        if crumbs.len() >= MAX_CRUMBS {
            crumbs.remove(0);
        }
        crumbs.push(here);
    }
}

/// The way back along the track, newest first, to the last point that is `clear` (the whole
/// track when none is).
fn track_back(crumbs: &[Vec3], clear: impl Fn(&Vec3) -> bool) -> Vec<Vec3> {
    match crumbs.iter().rposition(clear) {
        Some(k) => crumbs[k..].iter().rev().copied().collect(),
        None => crumbs.iter().rev().copied().collect(),
    }
}

impl Explore {
    /// Remembers where the drone flew (every `CRUMB_SPACING_M`), to find a landing spot.
    pub(super) fn drop_crumb(&mut self, ctx: &BehaviorContext) {
        let here = Vec3::new(ctx.position().x, ctx.position().y, self.base_z);
        push_crumb(&mut self.crumbs, here);
    }

    /// Lands here, or first flies back along its own track to the last point clear of every
    /// other drone (flying at its height or lower, or landed) when one is closer than
    /// `LANDING_CLEARANCE_M`: a drone never lands on another.
    pub(super) fn go_land(&mut self, ctx: &BehaviorContext) -> Result<(), Failure> {
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
            return self.land_here(ctx);
        }
        let back = track_back(&self.crumbs, clear);
        if back.is_empty() {
            return Err(Failure::new(
                FailureCode::Internal,
                "no clear place to land: another drone is below",
            ));
        }
        let follow = self.path_goal(ctx, &back);
        let mut child = FollowPath::new(follow);
        child.activate(ctx).map_err(|e| e.within("follow_path"))?;
        self.phase = Phase::Relocating(Box::new(child));
        Ok(())
    }

    /// Lands where the drone is (the `land` behavior as a child).
    pub(super) fn land_here(&mut self, ctx: &BehaviorContext) -> Result<(), Failure> {
        let mut land = Land::new(LandGoal { speed: 0.5 });
        land.activate(ctx).map_err(|e| e.within("land"))?;
        self.phase = Phase::Landing(Box::new(land));
        Ok(())
    }
}

/// Whether no cell of `grid` within `radius_m` of `p` (horizontally) is an obstacle.
pub(super) fn no_obstacle_within(
    grid: &OccupancyGrid,
    occupied: i8,
    p: &Vec3,
    radius_m: f64,
) -> bool {
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_track_keeps_a_point_a_metre_and_the_newest_points() {
        let mut crumbs = Vec::new();
        for x in [0.0, 0.5, 1.0, 1.9, 2.1] {
            push_crumb(&mut crumbs, Vec3::new(x, 0.0, 1.0));
        }
        let xs: Vec<f64> = crumbs.iter().map(|c| c.x).collect();
        assert_eq!(xs, [0.0, 1.0, 2.1]);
        for k in 0..MAX_CRUMBS {
            push_crumb(&mut crumbs, Vec3::new(10.0 + k as f64, 0.0, 1.0));
        }
        assert_eq!(crumbs.len(), MAX_CRUMBS);
        assert_eq!(
            crumbs.last().map(|c| c.x),
            Some(10.0 + (MAX_CRUMBS - 1) as f64)
        );
    }

    #[test]
    fn the_way_back_ends_at_the_last_clear_point_or_runs_the_whole_track() {
        let crumbs: Vec<Vec3> = (0..5).map(|x| Vec3::new(x as f64, 0.0, 1.0)).collect();
        let back = track_back(&crumbs, |p| p.x < 2.5);
        let xs: Vec<f64> = back.iter().map(|c| c.x).collect();
        assert_eq!(xs, [4.0, 3.0, 2.0]);
        assert_eq!(track_back(&crumbs, |_| false).len(), 5);
    }
}
