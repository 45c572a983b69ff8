//! The autopilot's velocity estimate checked against its own position.
//!
//! In: each LOCAL_POSITION_NED (the autopilot's boot time, position and velocity, in ENU). Out:
//! the horizontal bias of its velocity estimate (ENU, m/s): the reported velocity minus the
//! rate of change of the reported position, low-passed over [`VelocityCheck::filter_s`].
//!
//! Why: the autopilot's velocity loop holds its *estimate* at the command, so the vehicle flies
//! the command minus the estimate's error. On PX4 v1.16 SIH that error is 0.3 m/s at p50 and
//! up to 1.4 m/s for seconds while the position estimate stays within 0.2 m of the truth
//! (BENCHMARKS.md, "Driving PX4"): a hold drifted 1.6 m into a pole with Kestrel commanding the
//! way back. Kestrel therefore reads the vehicle's velocity as reported minus the bias (a
//! complementary filter: the velocity's short term, the position's long term) and sends each
//! velocity plus the bias, so what the vehicle flies is what Kestrel meant, and the speed
//! limits apply to that. With an estimator whose velocity agrees with its position the bias
//! stays near zero.

use crate::types::Vec3;

/// Largest bias taken (m/s): beyond it something else is wrong (a position reset the check
/// missed, a broken estimator), and chasing it would fly the vehicle fast.
pub const MAX_BIAS_MPS: f64 = 1.5;
/// A step whose rate differs from the reported velocity by more than this is an estimator
/// reset (a GPS glitch handled, an origin moved) or a late sample, not a bias: it is skipped
/// (m/s). A 0.3 m reset between two 50 Hz samples reads as 15 m/s.
const IMPLAUSIBLE_MPS: f64 = 3.0;
/// Samples further apart than this start the check afresh (s).
const MAX_GAP_S: f64 = 0.5;

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VelocityCheck {
    filter_s: f64,
    last: Option<Sample>,
    bias_enu_mps: Vec3,
}

#[derive(Debug, Clone, Copy, PartialEq)]
struct Sample {
    time_s: f64,
    position_enu_m: Vec3,
    velocity_enu_mps: Vec3,
}

impl VelocityCheck {
    /// `filter_s`: the low-pass time constant of the bias (the profile's
    /// `[drive] velocity_check_s`).
    pub fn new(filter_s: f64) -> Self {
        Self {
            filter_s: filter_s.max(0.0),
            last: None,
            bias_enu_mps: Vec3::zeros(),
        }
    }

    /// Starts again from nothing (a reboot, a lost link).
    pub fn reset(&mut self) {
        *self = Self::new(self.filter_s);
    }

    /// One LOCAL_POSITION_NED at the autopilot's boot time `time_s` (s).
    pub fn observe(&mut self, time_s: f64, position_enu_m: Vec3, velocity_enu_mps: Vec3) {
        let now = Sample {
            time_s,
            position_enu_m,
            velocity_enu_mps,
        };
        let Some(last) = self.last.replace(now) else {
            return;
        };
        let dt_s = time_s - last.time_s;
        if !(dt_s > 0.0 && dt_s <= MAX_GAP_S) {
            return;
        }
        let moved = (position_enu_m - last.position_enu_m) / dt_s;
        // The mean reported velocity over the step against the step itself.
        let mut residual = (velocity_enu_mps + last.velocity_enu_mps) / 2.0 - moved;
        residual.z = 0.0;
        if residual.norm() > IMPLAUSIBLE_MPS {
            return;
        }
        let follow = if self.filter_s > 0.0 {
            (dt_s / self.filter_s).min(1.0)
        } else {
            1.0
        };
        let bias = self.bias_enu_mps + (residual - self.bias_enu_mps) * follow;
        self.bias_enu_mps = bias.cap_magnitude(MAX_BIAS_MPS);
    }

    /// The horizontal bias of the autopilot's velocity estimate (ENU, m/s; z is 0).
    pub fn bias_enu_mps(&self) -> Vec3 {
        self.bias_enu_mps
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Feeds `seconds` of 50 Hz samples of a vehicle flying `truth` m/s while its estimate
    /// reports `truth + error`.
    fn fly(check: &mut VelocityCheck, from_s: f64, seconds: f64, truth: Vec3, error: Vec3) {
        let steps = (seconds * 50.0) as usize;
        for i in 0..=steps {
            let t = from_s + i as f64 * 0.02;
            check.observe(t, truth * t, truth + error);
        }
    }

    #[test]
    fn an_estimate_that_agrees_with_its_position_has_no_bias() {
        let mut check = VelocityCheck::new(0.2);
        fly(
            &mut check,
            0.0,
            5.0,
            Vec3::new(0.8, -0.3, 0.5),
            Vec3::zeros(),
        );
        assert!(check.bias_enu_mps().norm() < 1e-9);
    }

    #[test]
    fn a_velocity_estimate_off_by_a_steady_error_is_found_within_a_second() {
        let mut check = VelocityCheck::new(0.2);
        let error = Vec3::new(-0.6, 0.4, 0.3);
        fly(&mut check, 0.0, 1.0, Vec3::new(0.3, 0.0, 0.0), error);
        let bias = check.bias_enu_mps();
        assert!((bias - Vec3::new(-0.6, 0.4, 0.0)).norm() < 0.01, "{bias:?}");
    }

    #[test]
    fn a_position_reset_is_not_taken_for_motion() {
        for jump_m in [0.3, 5.0] {
            let mut check = VelocityCheck::new(0.2);
            fly(&mut check, 0.0, 1.0, Vec3::zeros(), Vec3::zeros());
            check.observe(1.04, Vec3::new(jump_m, 0.0, 0.0), Vec3::zeros());
            check.observe(1.06, Vec3::new(jump_m, 0.0, 0.0), Vec3::zeros());
            assert!(check.bias_enu_mps().norm() < 1e-9, "a {jump_m} m reset");
        }
    }

    #[test]
    fn the_bias_is_bounded_and_a_gap_starts_afresh() {
        let mut check = VelocityCheck::new(0.2);
        fly(
            &mut check,
            0.0,
            2.0,
            Vec3::zeros(),
            Vec3::new(2.0, 0.0, 0.0),
        );
        assert!((check.bias_enu_mps().norm() - MAX_BIAS_MPS).abs() < 1e-9);
        let before = check.bias_enu_mps();
        check.observe(3.0, Vec3::new(9.0, 0.0, 0.0), Vec3::zeros());
        assert_eq!(check.bias_enu_mps(), before, "a gap of 1 s is no step");
        check.reset();
        assert_eq!(check.bias_enu_mps(), Vec3::zeros());
    }
}
