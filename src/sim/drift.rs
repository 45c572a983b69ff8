//! Position-estimate drift of a simulated vehicle, as an optical-flow deck's estimate walks away
//! from the truth: the estimate moves off at a steady speed (`[sim] position_drift_mps`) in a
//! direction that wanders (a random walk of the drift's heading, about a radian in
//! [`HEADING_WANDER_S`]), so the offset is a random walk whose speed never exceeds the setting.
//! Only while the vehicle flies: on the ground the deck sees no motion and the estimate holds.
//! Horizontal only: height comes from a range sensor and the heading from a compass, neither
//! of which drifts this way.
//!
//! In: the speed, a seed, time steps and whether the vehicle flies. Out: the offset (estimate
//! minus truth, ENU m) and its rate (m/s). The same seed gives the same walk.

use crate::types::{Vec2, Vec3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use std::f64::consts::PI;

/// Time over which the drift's heading wanders by about a radian (s, one standard deviation):
/// the direction an optical-flow estimate errs in changes with the ground's texture and the
/// flight, over seconds rather than minutes.
pub const HEADING_WANDER_S: f64 = 10.0;

/// One vehicle's drifting estimate.
#[derive(Debug, Clone)]
pub struct EstimateDrift {
    speed_mps: f64,
    heading_rad: f64,
    offset_m: Vec2,
    drifting: bool,
    rng: ChaCha8Rng,
}

impl EstimateDrift {
    /// A walk at `speed_mps` (negative or not finite counts as 0) from no offset, its first
    /// heading drawn from `seed`.
    pub fn new(speed_mps: f64, seed: u64) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let heading_rad = rng.gen_range(-PI..PI);
        Self {
            speed_mps: if speed_mps.is_finite() {
                speed_mps.max(0.0)
            } else {
                0.0
            },
            heading_rad,
            offset_m: Vec2::zeros(),
            drifting: false,
            rng,
        }
    }

    /// Advances the walk by `dt_s` (the offset moves only while `flying`).
    pub fn step(&mut self, dt_s: f64, flying: bool) {
        self.drifting = flying && self.speed_mps > 0.0 && dt_s > 0.0;
        if !self.drifting {
            return;
        }
        let turn: f64 = self.rng.sample(StandardNormal);
        self.heading_rad += turn * (dt_s / HEADING_WANDER_S).sqrt();
        self.offset_m += self.rate_xy() * dt_s;
    }

    /// The estimate minus the truth (ENU m; z is 0).
    pub fn offset_m(&self) -> Vec3 {
        Vec3::new(self.offset_m.x, self.offset_m.y, 0.0)
    }

    /// How fast the offset changes now (ENU m/s): what the estimate's velocity adds to the
    /// truth's, so the estimate's position and velocity agree.
    pub fn rate_mps(&self) -> Vec3 {
        if self.drifting {
            let r = self.rate_xy();
            Vec3::new(r.x, r.y, 0.0)
        } else {
            Vec3::zeros()
        }
    }

    fn rate_xy(&self) -> Vec2 {
        Vec2::new(self.heading_rad.cos(), self.heading_rad.sin()) * self.speed_mps
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Offsets after each second of `seconds` of flight at 100 Hz.
    fn walk(speed_mps: f64, seed: u64, seconds: u32) -> Vec<Vec3> {
        let mut d = EstimateDrift::new(speed_mps, seed);
        (0..seconds)
            .map(|_| {
                for _ in 0..100 {
                    d.step(0.01, true);
                }
                d.offset_m()
            })
            .collect()
    }

    #[test]
    fn the_estimate_walks_off_no_faster_than_the_drift_speed() {
        let offsets = walk(0.02, 7, 600);
        let mut before = Vec3::zeros();
        for (k, o) in offsets.iter().enumerate() {
            assert!(
                (o - before).norm() <= 0.02 + 1e-9,
                "second {k}: moved {:.4} m",
                (o - before).norm()
            );
            assert_eq!(o.z, 0.0, "height does not drift");
            before = *o;
        }
        let end = offsets.last().unwrap().norm();
        // A wandering heading: far less than the 12 m of a straight line, but well away.
        assert!(end > 0.3 && end < 0.8 * 12.0, "{end:.2} m after 600 s");
    }

    #[test]
    fn the_walk_is_the_seeds_and_off_means_none() {
        assert_eq!(walk(0.02, 3, 60), walk(0.02, 3, 60));
        assert_ne!(walk(0.02, 3, 60), walk(0.02, 4, 60));
        assert!(walk(0.0, 3, 60).iter().all(|o| *o == Vec3::zeros()));
        assert!(walk(f64::NAN, 3, 60).iter().all(|o| *o == Vec3::zeros()));
    }

    #[test]
    fn on_the_ground_the_estimate_holds_and_its_rate_is_the_offsets() {
        let mut d = EstimateDrift::new(0.05, 1);
        for _ in 0..500 {
            d.step(0.01, false);
        }
        assert_eq!(d.offset_m(), Vec3::zeros());
        assert_eq!(d.rate_mps(), Vec3::zeros());
        let before = d.offset_m();
        d.step(0.01, true);
        let rate = d.rate_mps();
        assert!((rate.norm() - 0.05).abs() < 1e-12);
        assert!(((d.offset_m() - before) - rate * 0.01).norm() < 1e-12);
        d.step(0.01, false);
        assert_eq!(d.rate_mps(), Vec3::zeros(), "landed: no drift velocity");
    }
}
