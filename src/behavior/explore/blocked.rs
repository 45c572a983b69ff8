//! Whether the path being flown is still clear on the drone's map. The allocator planned it
//! through space seen free with the safety distance all around, so an obstacle within that
//! distance of what is left of it is news the plan did not have: with a drifting position
//! estimate, a pole mapped long ago sits where the estimate then put it, and its true place,
//! seen free back then, shows its first hits only as the drone comes close (BENCHMARKS.md,
//! "What a real drone has"). Such a path is dropped: the drone holds and asks again.
//!
//! In: the path handed to `follow_path`, then per tick the drone's position and map. Out:
//! whether the path ahead is blocked, checked at most every [`CHECK_PERIOD`] and only when the
//! map changed.

use crate::behavior::nav_path::NavPath;
use crate::behavior::BehaviorContext;
use crate::types::Vec3;
use std::time::Duration;

/// Shortest time between two checks.
const CHECK_PERIOD: Duration = Duration::from_millis(100);

/// The path flown and when it was last checked.
#[derive(Debug, Default)]
pub(super) struct PathWatch {
    path: Option<NavPath>,
    checked_revision: Option<u64>,
    checked_at: Duration,
}

impl PathWatch {
    /// Watches a new path from `start` through `waypoints`.
    pub fn follow(&mut self, start: Vec3, waypoints: &[Vec3]) {
        self.path = Some(NavPath::new(start, waypoints));
        self.checked_revision = None;
    }

    pub fn clear(&mut self) {
        self.path = None;
    }

    /// Whether an obstacle cell lies within `clearance_m` of the path ahead, beyond
    /// `clearance_m` of the drone (where it is cannot be avoided any more).
    pub fn blocked(&mut self, ctx: &BehaviorContext, clearance_m: f64) -> bool {
        let (Some(map), Some(path)) = (ctx.map, self.path.as_mut()) else {
            return false;
        };
        let since = ctx.now.saturating_sub(self.checked_at);
        if self.checked_revision == Some(map.revision()) || since < CHECK_PERIOD {
            return false;
        }
        self.checked_revision = Some(map.revision());
        self.checked_at = ctx.now;
        let here = ctx.position();
        path.advance(&here);
        let resolution_m = map.grid().spec().resolution_m;
        path.first_blocked(
            &here,
            map.grid(),
            map.occupied_threshold(),
            clearance_m,
            clearance_m + resolution_m,
        )
        .is_some()
    }
}
