//! Motion controller: turns a [`MotionReference`] and the current state into a [`Setpoint`].
//!
//! Position and trajectory references are closed with PIDs into a velocity command (with the
//! trajectory's velocity as feed-forward); velocity references pass through. Yaw angles are
//! closed with a P(ID) into a yaw rate. When the platform accepts only position setpoints the
//! controller forwards positions instead ("bypass", as Aerostack2's controller handler does).

use super::pid::{saturate_proportionally, Pid, PidGains};
use super::reference::{AcceptedSetpoints, MotionReference, Setpoint, YawTarget};
use crate::types::{wrap_angle_rad, EstimatedState, Vec3};
use serde::{Deserialize, Serialize};

/// Controller gains and limits (SI units; see the field names).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ControllerConfig {
    pub position: PidGains,
    pub trajectory: PidGains,
    /// Yaw angle loop; only the x component is used.
    pub yaw: PidGains,
    pub max_horizontal_speed_mps: f64,
    pub max_up_speed_mps: f64,
    pub max_down_speed_mps: f64,
    pub max_yaw_rate_radps: f64,
    /// Time constant of the autopilot's velocity response (s). Trajectory references add
    /// their acceleration times this to the velocity command, so the vehicle keeps up with a
    /// speeding-up reference instead of lagging and then overshooting the speed to catch up.
    pub velocity_lag_s: f64,
}

impl Default for ControllerConfig {
    fn default() -> Self {
        Self {
            // The integrals cancel a steady push (wind) of up to 0.6 m/s; the integration zone
            // and conditional integration keep them from winding up on long approaches.
            position: PidGains::uniform(1.2, 0.4, 0.0, 1.5).with_integral_zone(0.5),
            trajectory: PidGains::uniform(1.5, 0.4, 0.0, 1.5).with_integral_zone(0.5),
            yaw: PidGains::uniform(2.0, 0.0, 0.0, 0.0),
            max_horizontal_speed_mps: 8.0,
            max_up_speed_mps: 3.0,
            max_down_speed_mps: 1.5,
            max_yaw_rate_radps: 1.5,
            velocity_lag_s: 0.25,
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Mode {
    Position,
    Velocity,
    Trajectory,
}

pub struct Controller {
    config: ControllerConfig,
    accepted: AcceptedSetpoints,
    position_pid: Pid,
    trajectory_pid: Pid,
    yaw_pid: Pid,
    mode: Option<Mode>,
}

impl Controller {
    pub fn new(config: ControllerConfig, accepted: AcceptedSetpoints) -> Self {
        Self {
            position_pid: Pid::new(config.position),
            trajectory_pid: Pid::new(config.trajectory),
            yaw_pid: Pid::new(config.yaw),
            config,
            accepted,
            mode: None,
        }
    }

    pub fn config(&self) -> &ControllerConfig {
        &self.config
    }

    /// Forget integrators (after a mode change, landing, or a state reset).
    pub fn reset(&mut self) {
        self.position_pid.reset();
        self.trajectory_pid.reset();
        self.yaw_pid.reset();
        self.mode = None;
    }

    /// One control step. `dt_s` is the time since the previous step.
    pub fn update(
        &mut self,
        state: &EstimatedState,
        reference: &MotionReference,
        dt_s: f64,
    ) -> Setpoint {
        let mode = match reference {
            MotionReference::Position { .. } => Mode::Position,
            MotionReference::Velocity { .. } => Mode::Velocity,
            MotionReference::Trajectory { .. } => Mode::Trajectory,
        };
        if self.mode != Some(mode) {
            self.reset();
            self.mode = Some(mode);
        }
        let position = state.pose.position_m;
        match *reference {
            MotionReference::Position {
                position_enu_m,
                velocity_ff_enu_mps,
                yaw,
                max_speed_mps,
            } => {
                if !self.accepted.velocity && self.accepted.position {
                    return Setpoint::Position {
                        position_enu_m,
                        velocity_ff_enu_mps,
                        yaw,
                    };
                }
                let limit = self.speed_limits(max_speed_mps);
                let v = self
                    .position_pid
                    .update(position_enu_m - position, dt_s, limit);
                let v = self.clamp_velocity(v, max_speed_mps) + velocity_ff_enu_mps;
                self.velocity_setpoint(self.clamp_velocity(v, f64::INFINITY), yaw, state, dt_s)
            }
            MotionReference::Velocity {
                velocity_enu_mps,
                yaw,
            } => self.velocity_setpoint(
                self.clamp_velocity(velocity_enu_mps, f64::INFINITY),
                yaw,
                state,
                dt_s,
            ),
            MotionReference::Trajectory {
                position_enu_m,
                velocity_enu_mps,
                acceleration_enu_mps2,
                yaw,
            } => {
                if !self.accepted.velocity && self.accepted.position {
                    return Setpoint::Position {
                        position_enu_m,
                        velocity_ff_enu_mps: velocity_enu_mps,
                        yaw,
                    };
                }
                let correction =
                    self.trajectory_pid
                        .update(position_enu_m - position, dt_s, Vec3::zeros());
                let feed_forward =
                    velocity_enu_mps + acceleration_enu_mps2 * self.config.velocity_lag_s;
                let v = self.clamp_velocity(feed_forward + correction, f64::INFINITY);
                self.velocity_setpoint(v, yaw, state, dt_s)
            }
        }
    }

    fn speed_limits(&self, max_speed_mps: f64) -> Vec3 {
        let c = &self.config;
        let h = max_speed_mps.min(c.max_horizontal_speed_mps);
        Vec3::new(
            h,
            h,
            c.max_up_speed_mps
                .max(c.max_down_speed_mps)
                .min(max_speed_mps),
        )
    }

    /// Horizontal speed capped by `max_speed_mps` and the vehicle limit; vertical by up/down limits.
    fn clamp_velocity(&self, v: Vec3, max_speed_mps: f64) -> Vec3 {
        let c = &self.config;
        let h_cap = max_speed_mps.min(c.max_horizontal_speed_mps);
        let horizontal = v.xy();
        let h_norm = horizontal.norm();
        let horizontal = if h_norm > h_cap && h_norm > 0.0 {
            horizontal * (h_cap / h_norm)
        } else {
            horizontal
        };
        let z = v.z.clamp(
            -c.max_down_speed_mps.min(max_speed_mps),
            c.max_up_speed_mps.min(max_speed_mps),
        );
        Vec3::new(horizontal.x, horizontal.y, z)
    }

    fn velocity_setpoint(
        &mut self,
        velocity_enu_mps: Vec3,
        yaw: YawTarget,
        state: &EstimatedState,
        dt_s: f64,
    ) -> Setpoint {
        let max_rate = self.config.max_yaw_rate_radps;
        let rate = match yaw {
            YawTarget::Rate(r) => r.clamp(-max_rate, max_rate),
            YawTarget::Angle(target) => {
                let error = wrap_angle_rad(target - state.pose.yaw_rad());
                let out = self
                    .yaw_pid
                    .update(Vec3::new(error, 0.0, 0.0), dt_s, Vec3::zeros());
                saturate_proportionally(out, Vec3::new(max_rate, 0.0, 0.0)).x
            }
        };
        Setpoint::Velocity {
            velocity_enu_mps,
            yaw: YawTarget::Rate(rate),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::types::Pose;

    fn state_at(p: Vec3, yaw: f64) -> EstimatedState {
        EstimatedState {
            pose: Pose::from_position_yaw(p, yaw),
            ..Default::default()
        }
    }

    fn velocity_of(sp: Setpoint) -> (Vec3, f64) {
        match sp {
            Setpoint::Velocity {
                velocity_enu_mps,
                yaw: YawTarget::Rate(r),
            } => (velocity_enu_mps, r),
            other => panic!("expected a velocity setpoint, got {other:?}"),
        }
    }

    #[test]
    fn far_position_goal_is_capped_at_max_speed() {
        let mut c = Controller::new(
            ControllerConfig::default(),
            AcceptedSetpoints {
                velocity: true,
                position: true,
            },
        );
        let r = MotionReference::Position {
            position_enu_m: Vec3::new(100.0, 0.0, 0.0),
            velocity_ff_enu_mps: Vec3::zeros(),
            yaw: YawTarget::Angle(0.0),
            max_speed_mps: 2.0,
        };
        let (v, rate) = velocity_of(c.update(&state_at(Vec3::zeros(), 0.0), &r, 0.01));
        assert!((v.norm() - 2.0).abs() < 1e-9, "{v}");
        assert!(rate.abs() < 1e-12);
    }

    #[test]
    fn yaw_error_is_wrapped_and_rate_limited() {
        let mut c = Controller::new(
            ControllerConfig::default(),
            AcceptedSetpoints {
                velocity: true,
                position: true,
            },
        );
        // From 3.0 rad to -3.0 rad the short way is +0.28 rad, not -6 rad.
        let r = MotionReference::Position {
            position_enu_m: Vec3::zeros(),
            velocity_ff_enu_mps: Vec3::zeros(),
            yaw: YawTarget::Angle(-3.0),
            max_speed_mps: 1.0,
        };
        let (_, rate) = velocity_of(c.update(&state_at(Vec3::zeros(), 3.0), &r, 0.01));
        assert!(rate > 0.0 && rate <= 1.5);
    }

    #[test]
    fn position_only_platform_gets_position_setpoints() {
        let mut c = Controller::new(
            ControllerConfig::default(),
            AcceptedSetpoints {
                velocity: false,
                position: true,
            },
        );
        let goal = Vec3::new(1.0, 2.0, 3.0);
        let r = MotionReference::Position {
            position_enu_m: goal,
            velocity_ff_enu_mps: Vec3::zeros(),
            yaw: YawTarget::Angle(0.5),
            max_speed_mps: 1.0,
        };
        match c.update(&state_at(Vec3::zeros(), 0.0), &r, 0.01) {
            Setpoint::Position { position_enu_m, .. } => assert_eq!(position_enu_m, goal),
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn trajectory_feed_forward_passes_through_when_on_track() {
        let mut c = Controller::new(
            ControllerConfig::default(),
            AcceptedSetpoints {
                velocity: true,
                position: true,
            },
        );
        let r = MotionReference::Trajectory {
            position_enu_m: Vec3::new(1.0, 1.0, 1.0),
            velocity_enu_mps: Vec3::new(0.5, 0.0, 0.0),
            acceleration_enu_mps2: Vec3::zeros(),
            yaw: YawTarget::Rate(0.0),
        };
        let (v, _) = velocity_of(c.update(&state_at(Vec3::new(1.0, 1.0, 1.0), 0.0), &r, 0.01));
        assert!((v - Vec3::new(0.5, 0.0, 0.0)).norm() < 1e-9);
    }

    #[test]
    fn trajectory_acceleration_leads_the_velocity_command() {
        let mut c = Controller::new(
            ControllerConfig::default(),
            AcceptedSetpoints {
                velocity: true,
                position: true,
            },
        );
        let r = MotionReference::Trajectory {
            position_enu_m: Vec3::zeros(),
            velocity_enu_mps: Vec3::new(1.0, 0.0, 0.0),
            acceleration_enu_mps2: Vec3::new(2.0, 0.0, 0.0),
            yaw: YawTarget::Rate(0.0),
        };
        let (v, _) = velocity_of(c.update(&state_at(Vec3::zeros(), 0.0), &r, 0.01));
        assert!((v.x - (1.0 + 2.0 * 0.25)).abs() < 1e-9, "{v}");
    }

    #[test]
    fn descent_speed_is_limited() {
        let mut c = Controller::new(
            ControllerConfig::default(),
            AcceptedSetpoints {
                velocity: true,
                position: true,
            },
        );
        let r = MotionReference::Velocity {
            velocity_enu_mps: Vec3::new(0.0, 0.0, -5.0),
            yaw: YawTarget::Rate(0.0),
        };
        let (v, _) = velocity_of(c.update(&state_at(Vec3::zeros(), 0.0), &r, 0.01));
        assert!((v.z + 1.5).abs() < 1e-12);
    }
}
