//! How far a drone strays from the path it is given, as room the explorer adds to its safety
//! distance.
//!
//! In: each control tick, the reference the drone flies (point and velocity) and where the
//! drone is. Out: the extra distance (m, in whole steps of [`STEP_M`]) to keep from obstacles
//! and unknown space on top of the goal's `safety_distance`.
//!
//! The explorer plans through observed-free space at `safety_distance` from everything else,
//! assuming the drone flies its path. A real autopilot's own hold can wander 0.3-0.6 m (PX4 SIH,
//! BENCHMARKS.md "Driving PX4"), more than the room a 0.4 m safety distance leaves a 0.15 m
//! vehicle. Only the error across the path counts: a drone behind its moving reference is still
//! on its path. The estimate is the recent peak, coming down slowly ([`DECAY_MPS`]), so one calm
//! stretch does not undo what a gust showed.
//!
//! The reported position itself may walk: PX4 SIH's moved 0.8-1.7 m within 2 s beyond what its
//! own reported velocity integrates to (BENCHMARKS.md, "Three PX4 SIH exploring"), carrying the
//! drone's estimate toward a wall while the vehicle flew nowhere. That walk (the position against
//! the velocity integrated over about [`WALK_WINDOW_S`]) counts as straying too.
//!
//! Beside the slow peak, a quick one ([`RECENT_DECAY_MPS`]) says whether the drone holds its
//! path now: a drone boxed in by the room it keeps (a map correction's jump, one gust) may let
//! the room go once it does ([`TrackingMargin::relax`]), and earns it back by straying again.

use crate::types::Vec3;

/// Stray across the path that a safety distance already allows for (m): the simulator's
/// drones stray up to about 0.17 m in corners (p99 0.11 m), which needs no more room.
const ALLOWANCE_M: f64 = 0.2;
/// The extra room is rounded up to whole steps (m), so it changes seldom (each change
/// rebuilds the allocator's navigable space).
pub const STEP_M: f64 = 0.1;
/// The most extra room asked for (m): a drone that strays farther cannot explore a cluttered
/// world safely at all, and a wider margin would close every gap. PX4 SIH's estimate walked
/// about 1 m in the 2 s before a contact.
pub const MAX_EXTRA_M: f64 = 1.0;
/// Over about how long the position estimate's walk is measured (s).
const WALK_WINDOW_S: f64 = 2.0;
/// How fast the remembered peak comes down (m/s): 0.1 m per 20 s.
const DECAY_MPS: f64 = 0.005;
/// How fast the quick peak comes down (m/s): a 1 m stray is forgotten in 16 s of holding.
const RECENT_DECAY_MPS: f64 = 0.05;
/// Below this reference speed the whole horizontal error counts (m/s).
const MOVING_MPS: f64 = 0.1;

#[derive(Debug, Clone, Default)]
pub struct TrackingMargin {
    peak_m: f64,
    /// The same peak, coming down at [`RECENT_DECAY_MPS`].
    recent_m: f64,
    /// The horizontal position the reported velocity leads to, pulled toward the reported
    /// position over [`WALK_WINDOW_S`]: how far the two part is the walk of the last seconds.
    dead_reckoned: Option<Vec3>,
}

impl TrackingMargin {
    /// One tick: the reference's point and velocity, the drone's reported position and
    /// velocity, the time since the last tick.
    pub fn observe(
        &mut self,
        point: Vec3,
        velocity: Vec3,
        position: Vec3,
        vehicle_velocity: Vec3,
        dt_s: f64,
    ) {
        let error = (point - position).xy();
        let v = velocity.xy();
        let across = if v.norm() > MOVING_MPS {
            (error.x * v.y - error.y * v.x).abs() / v.norm()
        } else {
            error.norm()
        };
        let walk = self.walk_m(position, vehicle_velocity, dt_s);
        let stray = across.max(walk);
        if stray.is_finite() {
            self.peak_m = stray.max(self.peak_m - DECAY_MPS * dt_s.max(0.0));
            self.recent_m = stray.max(self.recent_m - RECENT_DECAY_MPS * dt_s.max(0.0));
        }
    }

    /// How far the reported position has lately moved beyond what the reported velocity
    /// explains (m, horizontal).
    fn walk_m(&mut self, position: Vec3, velocity: Vec3, dt_s: f64) -> f64 {
        let here = Vec3::new(position.x, position.y, 0.0);
        if !(here.iter().all(|c| c.is_finite()) && velocity.iter().all(|c| c.is_finite())) {
            return 0.0;
        }
        let dt_s = dt_s.clamp(0.0, WALK_WINDOW_S);
        let dr = self.dead_reckoned.get_or_insert(here);
        *dr += Vec3::new(velocity.x, velocity.y, 0.0) * dt_s;
        *dr += (here - *dr) * (dt_s / WALK_WINDOW_S);
        (here - *dr).norm()
    }

    /// The drone was held off its path by something other than itself (the safety stage
    /// keeping it from a peer): its reference running ahead is not a stray, and the walk
    /// starts anew from where it is.
    pub fn excuse(&mut self) {
        self.dead_reckoned = None;
    }

    /// The largest recent stray across the path (m).
    pub fn peak_m(&self) -> f64 {
        self.peak_m
    }

    /// The drone holds its path now: its stray of the last seconds is within the allowance.
    pub fn holds_path(&self) -> bool {
        self.recent_m <= ALLOWANCE_M
    }

    /// Lets the room go down to what the last seconds' stray asks for (none, when the drone
    /// [`Self::holds_path`]).
    pub fn relax(&mut self) {
        self.peak_m = self.peak_m.min(self.recent_m);
    }

    /// Extra distance to keep (m): the stray beyond the allowance, in whole steps, at most
    /// [`MAX_EXTRA_M`].
    pub fn extra_m(&self) -> f64 {
        let beyond = (self.peak_m - ALLOWANCE_M).max(0.0);
        ((beyond / STEP_M - 1e-9).ceil().max(0.0) * STEP_M).min(MAX_EXTRA_M)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The drone at `position`, still (its velocity and position agree).
    fn fly(m: &mut TrackingMargin, seconds: f64, point: Vec3, velocity: Vec3, position: Vec3) {
        for _ in 0..(seconds * 100.0) as usize {
            m.observe(point, velocity, position, Vec3::zeros(), 0.01);
        }
    }

    #[test]
    fn a_position_estimate_that_walks_without_velocity_counts_as_straying() {
        let mut m = TrackingMargin::default();
        // The drone flies its path at 0.5 m/s, estimate and velocity agreeing: no room.
        let v = Vec3::new(0.5, 0.0, 0.0);
        for k in 0..500 {
            let p = v * (k as f64 * 0.01);
            m.observe(p, v, p, v, 0.01);
        }
        assert_eq!(m.extra_m(), 0.0);
        // Hovering, the estimate walks 0.5 m/s north for 2 s while the velocity reads zero
        // (the reference follows it, as the explorer's hold would not: only the walk shows).
        let start = Vec3::new(2.5, 0.0, 0.0);
        for k in 0..200 {
            let p = start + Vec3::new(0.0, 0.5 * k as f64 * 0.01, 0.0);
            m.observe(p, Vec3::zeros(), p, Vec3::zeros(), 0.01);
        }
        assert!(m.peak_m() > 0.5, "{}", m.peak_m());
        assert!(m.extra_m() >= 0.4, "{}", m.extra_m());
    }

    #[test]
    fn a_drone_on_its_path_or_behind_on_it_needs_no_more_room() {
        let mut m = TrackingMargin::default();
        let along = Vec3::new(0.75, 0.0, 0.0);
        // 0.15 m across (the simulator's corners) and 0.5 m behind.
        fly(
            &mut m,
            5.0,
            Vec3::new(0.5, 0.15, 1.0),
            along,
            Vec3::new(0.0, 0.0, 1.0),
        );
        assert_eq!(m.extra_m(), 0.0);
    }

    #[test]
    fn a_drone_straying_across_its_path_gets_the_stray_beyond_the_allowance_in_steps() {
        let mut m = TrackingMargin::default();
        let along = Vec3::new(0.0, 0.5, 0.0);
        fly(&mut m, 1.0, Vec3::new(0.45, 0.0, 1.0), along, Vec3::zeros());
        assert!((m.extra_m() - 0.3).abs() < 1e-9, "{}", m.extra_m());
        // Hovering, the whole horizontal error counts.
        let mut m = TrackingMargin::default();
        fly(
            &mut m,
            1.0,
            Vec3::new(0.3, 0.3, 1.0),
            Vec3::zeros(),
            Vec3::zeros(),
        );
        assert!((m.extra_m() - 0.3).abs() < 1e-9, "{}", m.extra_m());
        // Never more than the most.
        fly(
            &mut m,
            1.0,
            Vec3::new(3.0, 0.0, 1.0),
            Vec3::zeros(),
            Vec3::zeros(),
        );
        assert_eq!(m.extra_m(), MAX_EXTRA_M);
    }

    #[test]
    fn the_room_comes_back_slowly_once_the_drone_holds_its_path() {
        let mut m = TrackingMargin::default();
        fly(
            &mut m,
            0.5,
            Vec3::new(0.5, 0.0, 1.0),
            Vec3::zeros(),
            Vec3::zeros(),
        );
        assert!((m.extra_m() - 0.3).abs() < 1e-9);
        let on_path = Vec3::zeros();
        fly(&mut m, 10.0, on_path, Vec3::zeros(), on_path);
        assert!((m.extra_m() - 0.3).abs() < 1e-9, "10 s: {}", m.extra_m());
        fly(&mut m, 60.0, on_path, Vec3::zeros(), on_path);
        assert_eq!(m.extra_m(), 0.0);
    }

    #[test]
    fn a_drone_holding_its_path_again_may_let_the_room_go_and_earns_it_back_by_straying() {
        let mut m = TrackingMargin::default();
        let on_path = Vec3::zeros();
        // A 0.8 m stray (a correction's jump), then 10 s on the path: still straying lately.
        fly(
            &mut m,
            0.1,
            Vec3::new(0.8, 0.0, 1.0),
            Vec3::zeros(),
            on_path,
        );
        fly(&mut m, 10.0, on_path, Vec3::zeros(), on_path);
        assert!(!m.holds_path());
        // 10 s more: it holds its path; the slow peak still keeps about half a metre.
        fly(&mut m, 10.0, on_path, Vec3::zeros(), on_path);
        assert!(m.holds_path());
        assert!(m.extra_m() >= 0.4, "{}", m.extra_m());
        m.relax();
        assert_eq!(m.extra_m(), 0.0);
        // Straying again brings the room back at once.
        fly(
            &mut m,
            0.1,
            Vec3::new(0.5, 0.0, 1.0),
            Vec3::zeros(),
            on_path,
        );
        assert!((m.extra_m() - 0.3).abs() < 1e-9, "{}", m.extra_m());
        assert!(!m.holds_path());
    }
}
