//! Progress toward a goal, for the behaviors that fail with `no_progress` when stuck (or
//! `fleet_peer_lost` when held for a silent peer).
//!
//! In: a distance still to go (m) each tick, the goal's threshold, the time. Out: how long it
//! has not shrunk. Far out, a step of 10 cm counts; near the goal, where an autopilot's own
//! hold wanders by a few tenths of a metre, half of what is left above the threshold counts,
//! so a vehicle that keeps closing in on its goal is never called stuck. And within
//! [`NEAR_GOAL_M`] of it, time counts at [`NEAR_GOAL_RATE`]: an autopilot whose own estimate
//! wanders (real PX4 SIH: its velocity estimate off by 0.3 m/s at p50, up to 0.9 m/s, so the
//! vehicle circles 0.2-0.8 m round the goal) passes within 0.1 m of it by chance, now and then,
//! and is given 60 s (by default) to do so rather than 20.

use super::server::seconds_since;
use super::{BehaviorContext, Failure, FailureCode};
use crate::types::DroneView;
use std::time::Duration;

/// A peer's drone that fell silent while flying and is not accounted for: the safety stage holds
/// this vehicle while there is one.
pub(crate) fn lost_peer<'a>(ctx: &BehaviorContext<'a>) -> Option<&'a DroneView> {
    ctx.fleet.others(ctx.drone_id).find(|d| d.unaccounted)
}

/// Why a vehicle made no progress for `no_progress_timeout_s`: held by the safety stage for a
/// peer's drone that fell silent while flying (`fleet_peer_lost`: every drone holds until it is
/// heard again or accounted for, which two Kestrels never are), else `no_progress` in `words`.
pub(crate) fn stuck(ctx: &BehaviorContext, words: String) -> Failure {
    match lost_peer(ctx) {
        Some(peer) => Failure::new(
            FailureCode::FleetPeerLost,
            format!(
                "fleet peer lost: {} fell silent while flying; holding until the peer is back \
                 or an operator lands it",
                peer.id
            ),
        ),
        None => Failure::new(FailureCode::NoProgress, words),
    }
}

/// The step that counts as progress far from the goal (m).
const STEP_M: f64 = 0.1;
/// The smallest step that counts near the goal (m): below it is noise.
const MIN_STEP_M: f64 = 0.01;
/// Within this of the goal (m) ...
pub(crate) const NEAR_GOAL_M: f64 = 0.5;
/// ... a second without progress counts this much.
pub(crate) const NEAR_GOAL_RATE: f64 = 1.0 / 3.0;

#[derive(Debug, Clone, Copy)]
pub(crate) struct Progress {
    best_m: f64,
    /// The time of the last update.
    at: Duration,
    /// Time without progress so far, as counted (s).
    stuck_s: f64,
    /// How much a second counts within [`NEAR_GOAL_M`] of the goal.
    near_goal_rate: f64,
}

impl Progress {
    /// Every second counts (a climb to a height, which autopilots hold well).
    pub(crate) fn new(now: Duration) -> Self {
        Self {
            best_m: f64::INFINITY,
            at: now,
            stuck_s: 0.0,
            near_goal_rate: 1.0,
        }
    }

    /// Toward a point flown to horizontally: near it, a second counts [`NEAR_GOAL_RATE`].
    pub(crate) fn toward_point(now: Duration) -> Self {
        Self {
            near_goal_rate: NEAR_GOAL_RATE,
            ..Self::new(now)
        }
    }

    /// Starts counting anew from `now` (after a pause), keeping the best distance.
    pub(crate) fn restart(&mut self, now: Duration) {
        self.at = now;
        self.stuck_s = 0.0;
    }

    /// Records `distance_m`; returns the seconds, as counted, since it last shrank by a step.
    pub(crate) fn update(&mut self, distance_m: f64, threshold_m: f64, now: Duration) -> f64 {
        let step = ((self.best_m - threshold_m) / 2.0).clamp(MIN_STEP_M, STEP_M);
        let elapsed_s = seconds_since(now, self.at);
        self.at = now;
        if distance_m < self.best_m - step || !self.best_m.is_finite() {
            self.best_m = distance_m;
            self.stuck_s = 0.0;
        } else if distance_m <= NEAR_GOAL_M {
            self.stuck_s += elapsed_s * self.near_goal_rate;
        } else {
            self.stuck_s += elapsed_s;
        }
        self.stuck_s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(s: f64) -> Duration {
        Duration::from_secs_f64(s)
    }

    #[test]
    fn far_out_only_ten_centimetres_count() {
        let mut p = Progress::new(at(0.0));
        assert_eq!(p.update(5.0, 0.1, at(0.0)), 0.0);
        assert_eq!(p.update(4.95, 0.1, at(10.0)), 10.0);
        assert_eq!(p.update(4.85, 0.1, at(12.0)), 0.0);
    }

    #[test]
    fn near_the_goal_a_vehicle_closing_in_slowly_is_not_stuck() {
        let mut p = Progress::toward_point(at(0.0));
        p.update(0.3, 0.1, at(0.0));
        // 0.1 m above the threshold: a 5 cm step counts (it would not at 10 cm).
        assert_eq!(p.update(0.19, 0.1, at(15.0)), 0.0);
        assert_eq!(p.update(0.14, 0.1, at(30.0)), 0.0);
        // Below a centimetre is noise; within half a metre, 30 s count as 10.
        assert_eq!(p.update(0.135, 0.1, at(60.0)), 10.0);
    }

    #[test]
    fn circling_near_the_goal_counts_a_third() {
        let mut p = Progress::toward_point(at(0.0));
        p.update(0.12, 0.1, at(0.0));
        let mut stuck = 0.0;
        for tick in 1..=590 {
            // Round the goal at 0.2-0.5 m, never nearer than the best.
            let d = 0.35 + 0.15 * (tick as f64 * 0.1).sin();
            stuck = p.update(d, 0.1, at(tick as f64 * 0.1));
        }
        assert!((stuck - 59.0 / 3.0).abs() < 1e-6, "{stuck}");
        // Away from the goal, every second counts.
        assert!((p.update(0.8, 0.1, at(60.0)) - (59.0 / 3.0 + 1.0)).abs() < 1e-6);
    }
}
