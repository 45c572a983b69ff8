//! Progress toward a goal, for the behaviors that fail with `no_progress` when stuck (or
//! `fleet_peer_lost` when held for a silent peer).
//!
//! In: a distance still to go (m) each tick, the goal's threshold, the time. Out: how long it
//! has not shrunk. Far out, a step of 10 cm counts; near the goal, where an autopilot's own
//! hold wanders by a few tenths of a metre, half of what is left above the threshold counts,
//! so a vehicle that keeps closing in on its goal is never called stuck.

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

#[derive(Debug, Clone, Copy)]
pub(crate) struct Progress {
    best_m: f64,
    at: Duration,
}

impl Progress {
    pub(crate) fn new(now: Duration) -> Self {
        Self {
            best_m: f64::INFINITY,
            at: now,
        }
    }

    /// Starts counting anew from `now` (after a pause), keeping the best distance.
    pub(crate) fn restart(&mut self, now: Duration) {
        self.at = now;
    }

    /// Records `distance_m`; returns the seconds since it last shrank by a step.
    pub(crate) fn update(&mut self, distance_m: f64, threshold_m: f64, now: Duration) -> f64 {
        let step = ((self.best_m - threshold_m) / 2.0).clamp(MIN_STEP_M, STEP_M);
        if distance_m < self.best_m - step || !self.best_m.is_finite() {
            self.best_m = distance_m;
            self.at = now;
        }
        seconds_since(now, self.at)
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
        let mut p = Progress::new(at(0.0));
        p.update(0.3, 0.1, at(0.0));
        // 0.1 m above the threshold: a 5 cm step counts (it would not at 10 cm).
        assert_eq!(p.update(0.19, 0.1, at(15.0)), 0.0);
        assert_eq!(p.update(0.14, 0.1, at(30.0)), 0.0);
        // Below a centimetre is noise.
        assert_eq!(p.update(0.135, 0.1, at(40.0)), 10.0);
    }
}
