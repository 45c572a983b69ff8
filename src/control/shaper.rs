//! Speed caps, and the reference point handed to an autopilot that closes its own position loop.
//!
//! In: a goal point (ENU m) with the goal's own velocity, the speed caps, the acceleration limit,
//! the vehicle's state and `dt`. Out: this tick's reference point and its velocity (the
//! feed-forward). The point moves toward the goal no faster than the caps and brakes within the
//! acceleration limit so that it stops on the goal. It never runs more than a leash ahead of the
//! vehicle: a vehicle held back (wind, the safety stage) never leaves a far target behind, which
//! an autopilot would fly to at its own top speed.

use crate::types::{EstimatedState, Vec3};

/// The reference point is kept within this distance of the vehicle (m).
pub const LEASH_M: f64 = 1.0;

/// Speed limits of one tick (m/s, all positive; `f64::INFINITY` for none).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SpeedCaps {
    pub horizontal_mps: f64,
    pub up_mps: f64,
    pub down_mps: f64,
}

impl SpeedCaps {
    /// The velocity with its horizontal part scaled down to the horizontal cap and its vertical
    /// part clamped to the climb and descent caps.
    pub fn clamp(&self, v: Vec3) -> Vec3 {
        let h = v.xy().norm();
        let scale = if h > self.horizontal_mps && h > 0.0 {
            self.horizontal_mps / h
        } else {
            1.0
        };
        Vec3::new(
            v.x * scale,
            v.y * scale,
            v.z.clamp(-self.down_mps, self.up_mps),
        )
    }

    /// `feed_forward + correction` within the caps, giving way on the feed-forward first: a
    /// vehicle pulled back onto its path slows down along it rather than leave it (scaling the
    /// sum would shrink the pull back and cut corners round obstacles).
    pub fn clamp_keeping(&self, feed_forward: Vec3, correction: Vec3) -> Vec3 {
        let h = self.horizontal_mps;
        let (f, c) = (feed_forward.xy(), correction.xy());
        let horizontal = if (f + c).norm() <= h {
            f + c
        } else if c.norm() >= h {
            c * (h / c.norm())
        } else {
            // The largest s in [0, 1] with |s f + c| = h.
            let (ff, fc, cc) = (f.norm_squared(), f.dot(&c), c.norm_squared());
            let s = ((-fc + (fc * fc - ff * (cc - h * h)).max(0.0).sqrt()) / ff).clamp(0.0, 1.0);
            f * s + c
        };
        Vec3::new(
            horizontal.x,
            horizontal.y,
            (feed_forward.z + correction.z).clamp(-self.down_mps, self.up_mps),
        )
    }

    /// The highest speed along the unit vector `dir` that keeps within every cap.
    pub fn along(&self, dir: &Vec3) -> f64 {
        let h = dir.xy().norm();
        let mut cap = f64::INFINITY;
        if h > 1e-9 {
            cap = cap.min(self.horizontal_mps / h);
        }
        if dir.z > 1e-9 {
            cap = cap.min(self.up_mps / dir.z);
        } else if dir.z < -1e-9 {
            cap = cap.min(self.down_mps / -dir.z);
        }
        cap
    }
}

/// The moving reference point; `reset` when the vehicle was driven some other way.
#[derive(Debug, Clone, Copy, Default)]
pub struct ReferenceShaper {
    position_enu_m: Option<Vec3>,
    velocity_enu_mps: Vec3,
}

impl ReferenceShaper {
    pub fn reset(&mut self) {
        *self = Self::default();
    }

    /// One step toward `goal_enu_m`; returns the reference point and its velocity.
    pub fn step(
        &mut self,
        goal_enu_m: Vec3,
        goal_velocity_enu_mps: Vec3,
        caps: SpeedCaps,
        acceleration_mps2: f64,
        vehicle: &EstimatedState,
        dt_s: f64,
    ) -> (Vec3, Vec3) {
        let here = vehicle.pose.position_m;
        let from = match self.position_enu_m {
            Some(p) => p,
            None => {
                // Start where the vehicle is, as it moves: no jump in the command.
                self.velocity_enu_mps = caps.clamp(vehicle.velocity_enu_mps);
                here
            }
        };
        let dt_s = dt_s.max(1e-3);
        let to_goal = goal_enu_m - from;
        let distance = to_goal.norm();
        let approach = match to_goal.try_normalize(1e-9) {
            Some(dir) => {
                let braking = (2.0 * acceleration_mps2 * distance).sqrt();
                dir * caps.along(&dir).min(braking).min(distance / dt_s)
            }
            None => Vec3::zeros(),
        };
        let wanted = caps.clamp(goal_velocity_enu_mps + approach);
        let change = wanted - self.velocity_enu_mps;
        let max_change = acceleration_mps2 * dt_s;
        let change = if change.norm() > max_change {
            change * (max_change / change.norm())
        } else {
            change
        };
        self.velocity_enu_mps += change;
        let mut next = from + self.velocity_enu_mps * dt_s;
        let lead = next - here;
        if lead.norm() > LEASH_M {
            next = here + lead * (LEASH_M / lead.norm());
        }
        self.position_enu_m = Some(next);
        (next, self.velocity_enu_mps)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::types::Pose;

    const CAPS: SpeedCaps = SpeedCaps {
        horizontal_mps: 1.0,
        up_mps: 0.5,
        down_mps: 0.3,
    };

    fn at(p: Vec3) -> EstimatedState {
        EstimatedState {
            pose: Pose::from_position_yaw(p, 0.0),
            ..Default::default()
        }
    }

    #[test]
    fn caps_scale_the_horizontal_part_and_clamp_the_vertical() {
        let v = CAPS.clamp(Vec3::new(3.0, 4.0, -2.0));
        assert!((v.xy().norm() - 1.0).abs() < 1e-12);
        assert!((v.x / v.y - 0.75).abs() < 1e-12);
        assert_eq!(v.z, -0.3);
        assert_eq!(CAPS.along(&Vec3::new(0.0, 0.0, 1.0)), 0.5);
    }

    #[test]
    fn the_pull_back_onto_the_path_is_kept_and_the_feed_forward_gives_way() {
        let caps = SpeedCaps {
            horizontal_mps: 0.75,
            up_mps: 1.0,
            down_mps: 1.0,
        };
        // Cruising east at the cap, 0.3 m/s of pull back north onto the path.
        let v = caps.clamp_keeping(Vec3::new(0.75, 0.0, 0.0), Vec3::new(0.0, 0.3, 0.0));
        assert!((v.xy().norm() - 0.75).abs() < 1e-9, "{v}");
        assert!((v.y - 0.3).abs() < 1e-9, "the pull back is whole: {v}");
        // A pull back alone beyond the cap is capped itself.
        let v = caps.clamp_keeping(Vec3::new(0.75, 0.0, 0.0), Vec3::new(0.0, 2.0, 0.0));
        assert!((v - Vec3::new(0.0, 0.75, 0.0)).norm() < 1e-9, "{v}");
        // Within the caps nothing changes.
        let v = caps.clamp_keeping(Vec3::new(0.3, 0.0, 0.1), Vec3::new(0.1, 0.1, 0.0));
        assert!((v - Vec3::new(0.4, 0.1, 0.1)).norm() < 1e-12);
    }

    #[test]
    fn the_point_cruises_at_the_cap_and_stops_on_the_goal() {
        let mut s = ReferenceShaper::default();
        let goal = Vec3::new(5.0, 0.0, 0.0);
        let mut vehicle = Vec3::zeros();
        let mut top: f64 = 0.0;
        let mut last = (Vec3::zeros(), Vec3::zeros());
        for _ in 0..1500 {
            last = s.step(goal, Vec3::zeros(), CAPS, 1.0, &at(vehicle), 0.01);
            top = top.max(last.1.norm());
            vehicle = last.0; // a vehicle that follows perfectly
        }
        assert!(top <= 1.0 + 1e-9, "{top}");
        assert!(top > 0.99);
        assert!((last.0 - goal).norm() < 1e-6, "{}", last.0);
        assert!(last.1.norm() < 1e-6);
    }

    #[test]
    fn the_point_never_runs_more_than_the_leash_ahead_of_a_held_vehicle() {
        let mut s = ReferenceShaper::default();
        for _ in 0..1000 {
            let (p, _) = s.step(
                Vec3::new(20.0, 0.0, 0.0),
                Vec3::zeros(),
                CAPS,
                1.0,
                &at(Vec3::zeros()),
                0.01,
            );
            assert!(p.norm() <= LEASH_M + 1e-9);
        }
    }

    #[test]
    fn it_starts_from_the_vehicle_moving_as_it_moves() {
        let mut s = ReferenceShaper::default();
        let mut state = at(Vec3::new(1.0, 2.0, 3.0));
        state.velocity_enu_mps = Vec3::new(0.8, 0.0, 0.0);
        let (p, v) = s.step(
            Vec3::new(1.0, 2.0, 3.0),
            Vec3::zeros(),
            CAPS,
            1.0,
            &state,
            0.01,
        );
        assert!((v.x - 0.79).abs() < 1e-9, "{v}");
        assert!((p - Vec3::new(1.0079, 2.0, 3.0)).norm() < 1e-9, "{p}");
    }
}
