//! What the range beams hit in the last seconds, kept off by the safety stage.
//!
//! Under a drifting estimate the map can disagree with the world by more than the room a path
//! keeps: a pole mapped minutes ago sits where the drone's estimate then put it, and a path
//! planned clear of it may lead into the pole itself. What the beams hit a few seconds ago is
//! placed with the estimate of a few seconds ago, which has drifted only centimetres since: the
//! stage keeps the vehicle off those hits whatever the map says.
//!
//! In: each tick's hits (the vehicle's reported frame, in which the estimate drifts smoothly
//! and never jumps) and the vehicle's reported position. Out: the hits within reach, each as the
//! horizontal direction from it to the vehicle and its distance, which cap the closing speed
//! ([`super::SafetyStage::off_seen`]).

use super::obstacles::Near;
use super::separation::{reaction_s, slide, stoppable_mps, Closing};
use super::{intended_velocity, OverrideKind, SafetyStage};
use crate::control::Setpoint;
use crate::types::{Vec2, Vec3};
use std::collections::VecDeque;

/// Hits are kept this long (s): a drift of a few cm/s moves them a few centimetres.
pub const SEEN_FOR_S: f64 = 5.0;
/// Most hits kept (5 s of a 20 Hz ranger of 16 beams).
const MAX_SEEN: usize = 1600;
/// The vehicle stops this far from a hit (m, centre to the hit): the simulated vehicle's
/// 0.15 m radius and room for the drift and the beam's own error.
pub const SEEN_KEEP_M: f64 = 0.3;
/// Hits farther than this beyond [`SEEN_KEEP_M`] are left out (m): at 0.75 m/s a vehicle
/// brakes within a few decimetres.
const SEEN_REACH_M: f64 = 1.0;

/// The recent hits of a drone whose estimate drifts, and the map correction's offset (the
/// position in the map's frame less it is the reported one, in which the hits are kept).
#[derive(Debug, Clone, Copy)]
pub struct Seen<'a> {
    pub hits: &'a SeenHits,
    pub map_offset_m: Vec3,
}

/// The recent hits, oldest first.
#[derive(Debug, Clone, Default)]
pub struct SeenHits {
    hits: VecDeque<(f64, Vec2)>,
}

impl SeenHits {
    /// Keeps the hits of `now_s` (reported frame, ENU m) and forgets those older than
    /// [`SEEN_FOR_S`]; non-finite hits are dropped.
    pub fn add(&mut self, now_s: f64, hits: impl IntoIterator<Item = Vec2>) {
        let finite = |h: &Vec2| h.x.is_finite() && h.y.is_finite();
        self.hits
            .extend(hits.into_iter().filter(finite).map(|h| (now_s, h)));
        while self.hits.len() > MAX_SEEN
            || self
                .hits
                .front()
                .is_some_and(|(t, _)| *t < now_s - SEEN_FOR_S)
        {
            self.hits.pop_front();
        }
    }

    /// The hits within `reach_m` of `here` (reported frame), horizontally.
    pub(super) fn within(&self, here: Vec3, reach_m: f64) -> Vec<Near> {
        let at = here.xy();
        if !(reach_m > 0.0 && at.x.is_finite() && at.y.is_finite()) {
            return Vec::new();
        }
        self.hits
            .iter()
            .filter_map(|(_, h)| {
                let d = at - h;
                let distance_m = d.norm();
                (distance_m <= reach_m).then(|| Near {
                    away: d
                        .try_normalize(1e-9)
                        .map_or_else(|| Vec3::new(1.0, 0.0, 0.0), |a| Vec3::new(a.x, a.y, 0.0)),
                    distance_m,
                })
            })
            .collect()
    }

    pub fn clear(&mut self) {
        self.hits.clear();
    }
}

impl SafetyStage {
    /// `sp` slid along the recent hits within reach so that it closes on none faster than it
    /// can stop [`SEEN_KEEP_M`] short of it (stopped when it cannot meet them all); `None` when
    /// it does already. `here` is in the map's frame.
    pub(super) fn off_seen(
        &self,
        here: Vec3,
        sp: Setpoint,
        seen: Seen,
    ) -> Option<(Setpoint, OverrideKind, String)> {
        let reported = here - seen.map_offset_m;
        let near = seen.hits.within(reported, SEEN_KEEP_M + SEEN_REACH_M);
        if near.is_empty() {
            return None;
        }
        let react_s = reaction_s(&self.config);
        let brake = self.config.braking_mps2.max(0.1);
        let limits: Vec<Closing> = near
            .iter()
            .map(|n| Closing {
                away: n.away,
                allowed_mps: stoppable_mps(n.distance_m - SEEN_KEEP_M, react_s, brake),
                stop_only: false,
            })
            .collect();
        let (asked, yaw) = intended_velocity(&sp, here, &self.position_loop);
        let v = slide(asked, &limits);
        if (v - asked).norm() < 1e-9 {
            return None;
        }
        let nearest = near
            .iter()
            .map(|n| n.distance_m)
            .fold(f64::INFINITY, f64::min);
        let why = format!(
            "{nearest:.2} m from what the range sensor hit in the last {SEEN_FOR_S:.0} s: \
             keeping at least {SEEN_KEEP_M:.1} m"
        );
        Some((
            Setpoint::Velocity {
                velocity_enu_mps: v,
                yaw,
            },
            OverrideKind::Obstacle,
            why,
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hits_are_kept_for_seconds_and_found_within_reach() {
        let mut seen = SeenHits::default();
        seen.add(0.0, [Vec2::new(1.0, 0.0), Vec2::new(f64::NAN, 0.0)]);
        seen.add(3.0, [Vec2::new(0.0, 3.0)]);
        let near = seen.within(Vec3::new(0.0, 0.0, 1.0), 1.5);
        assert_eq!(near.len(), 1);
        assert!((near[0].distance_m - 1.0).abs() < 1e-12);
        assert!((near[0].away - Vec3::new(-1.0, 0.0, 0.0)).norm() < 1e-12);
        seen.add(5.5, []);
        assert!(seen.within(Vec3::zeros(), 1.5).is_empty(), "forgotten");
        assert_eq!(seen.within(Vec3::zeros(), 3.5).len(), 1);
    }
}
