//! What the vehicle does on its own beyond what it was told: a velocity disturbance observer.
//!
//! In: each velocity command that went out (ENU, m/s, after the safety stage), the measured
//! velocity, the time step, and the autopilot's velocity lag (s). Out: the estimated velocity
//! the vehicle makes on its own (wind pushing it, the autopilot's own hold drifting), for the
//! position loop to take off its command.
//!
//! The autopilot is taken to follow a command with a first-order lag; what the measured
//! velocity does beyond that model, low-passed over [`FILTER_S`] and bounded by
//! [`MAX_ESTIMATE_MPS`], is the estimate. Horizontal only: vertically an autopilot's own
//! takeoff, its landing and the ground make the vehicle do what it was not told without any
//! push (a native takeoff climbing past a zero command read as a push down, and the loop then
//! held the vehicle 0.2 m short of its height). The position loop's integral does the same job from
//! the position error, but only once a drift has moved the vehicle for seconds: under real PX4
//! SIH's own wander (0.25 m/s, changing every few seconds) it lagged behind, and a `go_to` now
//! and then never came within 0.1 m of its goal (BENCHMARKS.md, "Holding a goal").

use crate::types::Vec3;

/// Low-pass time constant of the estimate (s): slower than the autopilot's response, so its
/// transients and the telemetry's delay pass, faster than a drift's few seconds.
pub const FILTER_S: f64 = 0.7;
/// Largest estimate (m/s): a steady wind or drift beyond it is left to the integral.
pub const MAX_ESTIMATE_MPS: f64 = 0.8;

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DisturbanceObserver {
    lag_s: f64,
    /// The last command that went out, while the observer runs.
    command_mps: Option<Vec3>,
    /// What the vehicle's velocity would be from the commands alone.
    predicted_mps: Option<Vec3>,
    estimate_mps: Vec3,
}

impl DisturbanceObserver {
    /// `lag_s`: the autopilot's velocity time constant (the profile's `velocity_lag_s`).
    pub fn new(lag_s: f64) -> Self {
        Self {
            lag_s: lag_s.max(0.0),
            command_mps: None,
            predicted_mps: None,
            estimate_mps: Vec3::zeros(),
        }
    }

    /// Forgets everything (on the ground, after a mode change, when not driving velocities).
    pub fn reset(&mut self) {
        *self = Self::new(self.lag_s);
    }

    /// The velocity command that went out this tick.
    pub fn commanded(&mut self, velocity_enu_mps: Vec3) {
        self.command_mps = Some(velocity_enu_mps);
    }

    /// One step with the velocity measured now, `dt_s` after the last command went out: the
    /// estimate. Zero until a command went out.
    pub fn update(&mut self, measured_enu_mps: Vec3, dt_s: f64) -> Vec3 {
        let Some(command) = self.command_mps else {
            return Vec3::zeros();
        };
        if dt_s <= 0.0 || dt_s.is_nan() {
            return self.estimate_mps;
        }
        let Some(predicted) = self.predicted_mps.as_mut() else {
            // The model starts from what the vehicle does now.
            self.predicted_mps = Some(measured_enu_mps);
            return self.estimate_mps;
        };
        let follow = if self.lag_s > 0.0 {
            (dt_s / self.lag_s).min(1.0)
        } else {
            1.0
        };
        *predicted += (command - *predicted) * follow;
        let mut residual = measured_enu_mps - *predicted;
        residual.z = 0.0;
        let smooth = (dt_s / FILTER_S).min(1.0);
        let estimate = self.estimate_mps + (residual - self.estimate_mps) * smooth;
        self.estimate_mps = estimate.cap_magnitude(MAX_ESTIMATE_MPS);
        self.estimate_mps
    }

    pub fn estimate_mps(&self) -> Vec3 {
        self.estimate_mps
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const DT: f64 = 0.01;

    /// A first-order vehicle of time constant `lag_s` that adds `push` to every command.
    struct Vehicle {
        lag_s: f64,
        velocity: Vec3,
    }

    impl Vehicle {
        fn step(&mut self, command: Vec3, push: Vec3) {
            self.velocity += (command + push - self.velocity) * (DT / self.lag_s);
        }
    }

    #[test]
    fn a_steady_push_is_estimated_and_its_sign_is_the_pushs() {
        let mut observer = DisturbanceObserver::new(0.6);
        let mut vehicle = Vehicle {
            lag_s: 0.6,
            velocity: Vec3::zeros(),
        };
        let push = Vec3::new(0.25, -0.1, 0.0);
        let mut estimate = Vec3::zeros();
        for _ in 0..1000 {
            // As the controller: measure, command (taking the estimate off, as the position
            // loop does), and the vehicle moves until the next tick.
            estimate = observer.update(vehicle.velocity, DT);
            let command = -estimate;
            observer.commanded(command);
            vehicle.step(command, push);
        }
        assert!((estimate - push).norm() < 0.01, "{estimate} vs {push}");
        assert!(vehicle.velocity.norm() < 0.01, "{}", vehicle.velocity);
    }

    #[test]
    fn vertical_motion_is_never_taken_for_a_push() {
        let mut observer = DisturbanceObserver::new(0.6);
        for _ in 0..500 {
            // Told to hold, climbing at 1 m/s (the autopilot's own takeoff).
            observer.update(Vec3::new(0.0, 0.0, 1.0), DT);
            observer.commanded(Vec3::zeros());
        }
        assert_eq!(observer.estimate_mps(), Vec3::zeros());
    }

    #[test]
    fn a_vehicle_that_does_what_it_is_told_shows_no_disturbance() {
        let mut observer = DisturbanceObserver::new(0.6);
        let mut vehicle = Vehicle {
            lag_s: 0.6,
            velocity: Vec3::zeros(),
        };
        for i in 0..1000 {
            let estimate = observer.update(vehicle.velocity, DT);
            assert!(estimate.norm() < 1e-9, "{estimate} at step {i}");
            let command = Vec3::new(if i < 500 { 1.0 } else { -0.5 }, 0.3, 0.0);
            observer.commanded(command);
            vehicle.step(command, Vec3::zeros());
        }
    }

    #[test]
    fn the_estimate_is_bounded_and_nothing_without_a_command() {
        let mut observer = DisturbanceObserver::new(0.6);
        assert_eq!(observer.update(Vec3::new(3.0, 0.0, 0.0), DT), Vec3::zeros());
        // Told to stay, measured moving at 3 m/s for seconds: at most the bound.
        for _ in 0..1000 {
            observer.update(Vec3::zeros(), DT);
            observer.commanded(Vec3::zeros());
        }
        for _ in 0..1000 {
            observer.update(Vec3::new(3.0, 0.0, 0.0), DT);
            observer.commanded(Vec3::zeros());
        }
        let e = observer.estimate_mps();
        assert!((e.norm() - MAX_ESTIMATE_MPS).abs() < 1e-9, "{e}");
        observer.reset();
        assert_eq!(observer.estimate_mps(), Vec3::zeros());
    }
}
