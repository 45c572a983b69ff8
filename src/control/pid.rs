//! Three-axis PID with integral anti-windup, filtered derivative and output saturation.

use crate::types::Vec3;
use serde::{Deserialize, Serialize};

/// Gains for one PID; per-axis vectors (x, y, z in the frame of the error).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PidGains {
    pub kp: Vec3,
    pub ki: Vec3,
    pub kd: Vec3,
    /// Limit of the integral term's accumulated error (error unit x s); 0 disables the clamp.
    pub integral_limit: Vec3,
    /// Weight of the newest sample in the derivative low-pass filter (0..=1, 1 = no filter).
    pub derivative_alpha: f64,
    /// The integral only accumulates while the error is within this band (error unit; 0 =
    /// always), so it trims a steady offset without adding overshoot to large moves.
    #[serde(default)]
    pub integral_zone: Vec3,
}

impl PidGains {
    pub fn uniform(kp: f64, ki: f64, kd: f64, integral_limit: f64) -> Self {
        Self {
            kp: Vec3::repeat(kp),
            ki: Vec3::repeat(ki),
            kd: Vec3::repeat(kd),
            integral_limit: Vec3::repeat(integral_limit),
            derivative_alpha: 0.3,
            integral_zone: Vec3::zeros(),
        }
    }

    /// The same gains with an integration band (see `integral_zone`).
    pub fn with_integral_zone(self, zone: f64) -> Self {
        Self {
            integral_zone: Vec3::repeat(zone),
            ..self
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pid {
    gains: PidGains,
    integral: Vec3,
    derivative: Vec3,
    previous_error: Option<Vec3>,
}

impl Pid {
    pub fn new(gains: PidGains) -> Self {
        Self {
            gains,
            integral: Vec3::zeros(),
            derivative: Vec3::zeros(),
            previous_error: None,
        }
    }

    pub fn reset(&mut self) {
        self.integral = Vec3::zeros();
        self.derivative = Vec3::zeros();
        self.previous_error = None;
    }

    /// One step: `error` = reference - measurement, `dt_s` > 0. The output is scaled as a whole
    /// (keeping its direction) so that no axis exceeds `limit`; a limit axis of 0 means unlimited.
    pub fn update(&mut self, error: Vec3, dt_s: f64, limit: Vec3) -> Vec3 {
        if dt_s <= 0.0 {
            return self.output(error, limit);
        }
        let before = self.integral;
        for i in 0..3 {
            let zone = self.gains.integral_zone[i];
            if zone <= 0.0 || error[i].abs() <= zone {
                self.integral[i] += error[i] * dt_s;
            }
        }
        for i in 0..3 {
            let cap = self.gains.integral_limit[i];
            if cap > 0.0 {
                self.integral[i] = self.integral[i].clamp(-cap, cap);
            }
            // Conditional reset: an integral fighting the error sign is dropped.
            if cap > 0.0
                && self.integral[i].abs() >= cap
                && self.integral[i].signum() != error[i].signum()
            {
                self.integral[i] = 0.0;
            }
        }
        if let Some(prev) = self.previous_error {
            let raw = (error - prev) / dt_s;
            let a = self.gains.derivative_alpha;
            self.derivative = raw * a + self.derivative * (1.0 - a);
        }
        self.previous_error = Some(error);
        // Conditional integration: while the output saturates, the integral must not grow, or
        // it winds up during a long approach and overshoots the goal.
        if is_saturated(&self.raw_output(error), &limit) {
            for i in 0..3 {
                if self.integral[i].abs() > before[i].abs() {
                    self.integral[i] = before[i];
                }
            }
        }
        self.output(error, limit)
    }

    /// Carries the horizontal integral's forward push (along `from`, the reference's previous
    /// velocity) over to `to`, its velocity now: turned to the new direction and scaled by how
    /// much of the old velocity goes on along it, never grown (so it goes with a stop, and
    /// with a turn of a right angle or more). A lag learnt behind a moving reference (an
    /// autopilot that answers late) belongs to that motion: kept in place it would push the
    /// vehicle across the next leg of a path, or on past the point where the reference
    /// stopped. A push against the motion (a tailwind's trim), across it and vertical stays.
    pub fn carry_forward_integral(&mut self, from: Vec3, to: Vec3) {
        let from_speed = from.xy().norm();
        if from_speed < 1e-6 {
            return;
        }
        let heading = Vec3::new(from.x, from.y, 0.0) / from_speed;
        let along = self.integral.dot(&heading);
        if along <= 0.0 {
            return;
        }
        let to_h = Vec3::new(to.x, to.y, 0.0);
        let kept = (to_h.dot(&heading) / from_speed).clamp(0.0, 1.0);
        let onto = if to_h.norm() > 1e-6 {
            to_h / to_h.norm()
        } else {
            heading
        };
        self.integral += onto * (along * kept) - heading * along;
        for i in 0..3 {
            let cap = self.gains.integral_limit[i];
            if cap > 0.0 {
                self.integral[i] = self.integral[i].clamp(-cap, cap);
            }
        }
    }

    fn raw_output(&self, error: Vec3) -> Vec3 {
        let g = &self.gains;
        g.kp.component_mul(&error)
            + g.ki.component_mul(&self.integral)
            + g.kd.component_mul(&self.derivative)
    }

    fn output(&self, error: Vec3, limit: Vec3) -> Vec3 {
        saturate_proportionally(self.raw_output(error), limit)
    }
}

fn is_saturated(v: &Vec3, limit: &Vec3) -> bool {
    (0..3).any(|i| limit[i] > 0.0 && v[i].abs() > limit[i])
}

/// Scales `v` so each axis fits within `limit` (0 = unlimited), keeping its direction.
pub fn saturate_proportionally(v: Vec3, limit: Vec3) -> Vec3 {
    let mut scale: f64 = 1.0;
    for i in 0..3 {
        if limit[i] > 0.0 && v[i].abs() > limit[i] {
            scale = scale.min(limit[i] / v[i].abs());
        }
    }
    v * scale
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn proportional_only_matches_kp_times_error() {
        let mut pid = Pid::new(PidGains::uniform(2.0, 0.0, 0.0, 0.0));
        let out = pid.update(Vec3::new(1.0, -0.5, 0.25), 0.01, Vec3::zeros());
        assert!((out - Vec3::new(2.0, -1.0, 0.5)).norm() < 1e-12);
    }

    #[test]
    fn integral_is_clamped_by_anti_windup() {
        let mut pid = Pid::new(PidGains::uniform(0.0, 1.0, 0.0, 0.5));
        for _ in 0..1000 {
            pid.update(Vec3::new(1.0, 0.0, 0.0), 0.01, Vec3::zeros());
        }
        let out = pid.update(Vec3::new(1.0, 0.0, 0.0), 0.01, Vec3::zeros());
        assert!(
            (out.x - 0.5).abs() < 1e-9,
            "integral output capped at ki * limit, got {}",
            out.x
        );
    }

    #[test]
    fn integral_does_not_wind_up_while_the_output_saturates() {
        let mut pid = Pid::new(PidGains::uniform(1.0, 1.0, 0.0, 10.0));
        let limit = Vec3::repeat(1.0);
        for _ in 0..500 {
            pid.update(Vec3::new(5.0, 0.0, 0.0), 0.01, limit);
        }
        // Arrived: with a wound-up integral the output would still push on past the goal.
        let out = pid.update(Vec3::zeros(), 0.01, limit);
        assert!(out.x.abs() < 1e-9, "integral wound up to {}", out.x);
        // Unsaturated, the integral builds up as usual.
        for _ in 0..100 {
            pid.update(Vec3::new(0.1, 0.0, 0.0), 0.01, limit);
        }
        let out = pid.update(Vec3::zeros(), 0.01, limit);
        assert!((out.x - 0.1).abs() < 0.01, "{}", out.x);
    }

    #[test]
    fn integral_accumulates_only_inside_its_zone() {
        let mut pid = Pid::new(PidGains::uniform(0.0, 1.0, 0.0, 0.0).with_integral_zone(0.5));
        pid.update(Vec3::new(2.0, 0.4, 0.0), 1.0, Vec3::zeros());
        let out = pid.update(Vec3::zeros(), 1.0, Vec3::zeros());
        assert!((out - Vec3::new(0.0, 0.4, 0.0)).norm() < 1e-12, "{out}");
    }

    #[test]
    fn saturation_keeps_direction() {
        let v = saturate_proportionally(Vec3::new(4.0, 2.0, 0.0), Vec3::new(1.0, 1.0, 1.0));
        assert!((v - Vec3::new(1.0, 0.5, 0.0)).norm() < 1e-12);
        let free = saturate_proportionally(Vec3::new(4.0, 2.0, 0.0), Vec3::zeros());
        assert_eq!(free, Vec3::new(4.0, 2.0, 0.0));
    }

    #[test]
    fn derivative_reacts_to_error_change() {
        let mut pid = Pid::new(PidGains {
            derivative_alpha: 1.0,
            ..PidGains::uniform(0.0, 0.0, 1.0, 0.0)
        });
        pid.update(Vec3::zeros(), 0.1, Vec3::zeros());
        let out = pid.update(Vec3::new(1.0, 0.0, 0.0), 0.1, Vec3::zeros());
        assert!((out.x - 10.0).abs() < 1e-9);
    }
}
