//! Motion controller: turns a [`MotionReference`] and the current state into a [`Setpoint`].
//!
//! Position and trajectory references are closed with PIDs into a velocity command (with the
//! trajectory's velocity as feed-forward); velocity references pass through. Yaw angles are
//! closed with a P(ID) into a yaw rate. When the platform accepts only position setpoints the
//! controller forwards positions instead ("bypass", as Aerostack2's controller handler does).

use super::disturbance::DisturbanceObserver;
use super::pid::{saturate_proportionally, Pid, PidGains};
use super::reference::{AcceptedSetpoints, MotionReference, Setpoint, YawTarget};
use super::shaper::{ReferenceShaper, SpeedCaps};
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
    /// Absent: the platform profile's (`[drive] velocity_lag_s`), else 0.25 s.
    pub velocity_lag_s: Option<f64>,
    /// How much faster than a velocity it is sent the vehicle may fly, as a fraction: every
    /// speed cap is divided by one plus it, so the flown speed holds the limit. Absent: the
    /// platform profile's (`[drive] velocity_overshoot`), else 0.
    pub velocity_overshoot: Option<f64>,
    /// How much faster than a turn rate it is sent the vehicle may turn, as a fraction: every
    /// turn rate is sent divided by one plus it. Absent: the platform profile's
    /// (`[drive] yaw_rate_overshoot`), else 0.
    pub yaw_rate_overshoot: Option<f64>,
    /// Acceleration of the reference point handed to an autopilot that closes the position
    /// loop itself (m/s^2): how fast it speeds up toward a goal and brakes onto it.
    pub max_acceleration_mps2: f64,
    /// How fast the vehicle's position estimate may drift (m/s; the map correction's
    /// `drift_mps`, set by the core, not read from the config): the vehicle flies its estimate,
    /// so it truly moves up to this much faster than the estimate says, and every horizontal
    /// cap is this much lower.
    #[serde(skip)]
    pub estimate_drift_mps: f64,
}

impl ControllerConfig {
    /// The velocity response's time constant in use (s).
    pub fn velocity_lag(&self) -> f64 {
        self.velocity_lag_s.unwrap_or(DEFAULT_VELOCITY_LAG_S)
    }

    /// The share of a speed limit that is commanded, so that the vehicle's overshoot stays
    /// within the limit (1 when the vehicle flies what it is sent).
    pub fn commanded_speed_share(&self) -> f64 {
        commanded_speed_share(self.velocity_overshoot)
    }
}

/// The horizontal speed to plan and command for a limit (m/s): within the vehicle's
/// overshoot (`share`, [`commanded_speed_share`]) and less the drift of its estimate, but never
/// below half of what the overshoot alone leaves (a limit slower than the drift still moves).
pub fn commanded_horizontal_speed(limit_mps: f64, share: f64, estimate_drift_mps: f64) -> f64 {
    let sent = limit_mps * share;
    (sent - estimate_drift_mps.max(0.0)).max(sent / 2.0)
}

/// The share of a speed limit to plan and command with, for a vehicle that flies up to
/// `overshoot` (a fraction) faster than it is sent.
pub fn commanded_speed_share(overshoot: Option<f64>) -> f64 {
    1.0 / (1.0 + overshoot.unwrap_or(0.0).max(0.0))
}

/// The velocity lag assumed when neither the config nor the platform says (s).
pub const DEFAULT_VELOCITY_LAG_S: f64 = 0.25;

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
            velocity_lag_s: None,
            velocity_overshoot: None,
            estimate_drift_mps: 0.0,
            yaw_rate_overshoot: None,
            max_acceleration_mps2: 1.5,
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
    /// The moving reference point given to an autopilot that closes the position loop.
    shaper: ReferenceShaper,
    /// What the vehicle does beyond its velocity commands, taken off a position hold's.
    disturbance: DisturbanceObserver,
    /// The trajectory reference's velocity at the previous tick.
    reference_velocity: Option<Vec3>,
    mode: Option<Mode>,
}

impl Controller {
    pub fn new(config: ControllerConfig, accepted: AcceptedSetpoints) -> Self {
        Self {
            position_pid: Pid::new(config.position),
            trajectory_pid: Pid::new(config.trajectory),
            yaw_pid: Pid::new(config.yaw),
            shaper: ReferenceShaper::default(),
            disturbance: DisturbanceObserver::new(config.velocity_lag()),
            config,
            accepted,
            reference_velocity: None,
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
        self.shaper.reset();
        self.disturbance.reset();
        self.reference_velocity = None;
        self.mode = None;
    }

    /// What went out this tick, after the safety stage, and whether the vehicle is flying (not
    /// on the ground, taking off or landing): the disturbance observer runs only on the
    /// velocity commands of a flying vehicle (on the ground, a command to climb or sink that
    /// the ground stops would read as a push).
    pub fn sent(&mut self, setpoint: Option<&Setpoint>, flying: bool) {
        match setpoint {
            Some(Setpoint::Velocity {
                velocity_enu_mps, ..
            }) if flying => self.disturbance.commanded(*velocity_enu_mps),
            _ => self.disturbance.reset(),
        }
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
        let caps = self.caps(reference.max_speed_mps());
        let position = state.pose.position_m;
        let autopilot_loop = !self.accepted.velocity || self.accepted.position_loop.is_some();
        match *reference {
            MotionReference::Position {
                position_enu_m,
                velocity_ff_enu_mps,
                yaw,
                ..
            } if autopilot_loop && self.accepted.position => {
                let (point, velocity) = self.shaper.step(
                    position_enu_m,
                    velocity_ff_enu_mps,
                    caps,
                    self.config.max_acceleration_mps2,
                    state,
                    dt_s,
                );
                self.position_setpoint(point, velocity, caps, yaw, state, dt_s)
            }
            MotionReference::Trajectory {
                position_enu_m,
                velocity_enu_mps,
                yaw,
                ..
            } if autopilot_loop && self.accepted.position => {
                self.position_setpoint(position_enu_m, velocity_enu_mps, caps, yaw, state, dt_s)
            }
            MotionReference::Position {
                position_enu_m,
                velocity_ff_enu_mps,
                yaw,
                ..
            } => {
                let v = self.position_pid.update(
                    position_enu_m - position,
                    dt_s,
                    Vec3::new(
                        caps.horizontal_mps,
                        caps.horizontal_mps,
                        caps.up_mps.max(caps.down_mps),
                    ),
                );
                let push = if state.valid.velocity {
                    self.disturbance.update(state.velocity_enu_mps, dt_s)
                } else {
                    Vec3::zeros()
                };
                let v = caps.clamp(caps.clamp(v) + velocity_ff_enu_mps - push);
                self.velocity_setpoint(v, yaw, state, dt_s)
            }
            MotionReference::Velocity {
                velocity_enu_mps,
                yaw,
            } => self.velocity_setpoint(caps.clamp(velocity_enu_mps), yaw, state, dt_s),
            MotionReference::Trajectory {
                position_enu_m,
                velocity_enu_mps,
                acceleration_enu_mps2,
                yaw,
                ..
            } => {
                self.follow_reference_velocity(velocity_enu_mps);
                let correction =
                    self.trajectory_pid
                        .update(position_enu_m - position, dt_s, Vec3::zeros());
                let feed_forward =
                    velocity_enu_mps + acceleration_enu_mps2 * self.config.velocity_lag();
                let v = caps.clamp_keeping(feed_forward, correction);
                self.velocity_setpoint(v, yaw, state, dt_s)
            }
        }
    }

    /// Carries the trajectory integral's forward push along with the reference's velocity
    /// (see [`Pid::carry_forward_integral`]).
    fn follow_reference_velocity(&mut self, velocity_enu_mps: Vec3) {
        if let Some(before) = self.reference_velocity {
            self.trajectory_pid
                .carry_forward_integral(before, velocity_enu_mps);
        }
        self.reference_velocity = Some(velocity_enu_mps);
    }

    /// The caps of this tick: the reference's speed and the vehicle's limits, whichever is lower.
    pub fn caps(&self, max_speed_mps: f64) -> SpeedCaps {
        let c = &self.config;
        let share = c.commanded_speed_share();
        SpeedCaps {
            horizontal_mps: commanded_horizontal_speed(
                max_speed_mps.min(c.max_horizontal_speed_mps),
                share,
                c.estimate_drift_mps,
            ),
            up_mps: max_speed_mps.min(c.max_up_speed_mps) * share,
            down_mps: max_speed_mps.min(c.max_down_speed_mps) * share,
        }
    }

    /// A reference point for an autopilot that closes the position loop. Its feed-forward is
    /// chosen so that what the autopilot commands, feed-forward plus its own correction toward
    /// the point, stays within the caps. A position-only platform gets the point and the
    /// heading; one that takes velocities too gets the heading as a limited turn rate.
    fn position_setpoint(
        &mut self,
        point_enu_m: Vec3,
        velocity_enu_mps: Vec3,
        caps: SpeedCaps,
        yaw: YawTarget,
        state: &EstimatedState,
        dt_s: f64,
    ) -> Setpoint {
        let velocity_ff_enu_mps = match self.accepted.position_loop {
            Some(autopilot) => {
                let correction = autopilot.correction(point_enu_m - state.pose.position_m);
                caps.clamp(velocity_enu_mps + correction) - correction
            }
            None => caps.clamp(velocity_enu_mps),
        };
        let yaw = if self.accepted.velocity {
            self.yaw_rate(yaw, state, dt_s)
        } else {
            yaw
        };
        Setpoint::Position {
            position_enu_m: point_enu_m,
            velocity_ff_enu_mps,
            yaw,
        }
    }

    fn velocity_setpoint(
        &mut self,
        velocity_enu_mps: Vec3,
        yaw: YawTarget,
        state: &EstimatedState,
        dt_s: f64,
    ) -> Setpoint {
        Setpoint::Velocity {
            velocity_enu_mps,
            yaw: self.yaw_rate(yaw, state, dt_s),
        }
    }

    /// The heading as a turn rate within the limit, held back for the vehicle's overshoot.
    fn yaw_rate(&mut self, yaw: YawTarget, state: &EstimatedState, dt_s: f64) -> YawTarget {
        let max_rate = self.config.max_yaw_rate_radps;
        let share = commanded_speed_share(self.config.yaw_rate_overshoot);
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
        YawTarget::Rate(rate * share)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::types::{Pose, PositionLoop};

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
                position_loop: None,
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
                position_loop: None,
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
    fn position_only_platform_gets_a_point_that_moves_to_the_goal_within_the_speed() {
        let mut c = Controller::new(
            ControllerConfig::default(),
            AcceptedSetpoints {
                velocity: false,
                position: true,
                position_loop: None,
            },
        );
        let goal = Vec3::new(1.0, 2.0, 3.0);
        let r = MotionReference::Position {
            position_enu_m: goal,
            velocity_ff_enu_mps: Vec3::zeros(),
            yaw: YawTarget::Angle(0.5),
            max_speed_mps: 1.0,
        };
        let mut here = Vec3::zeros();
        for tick in 0..1000 {
            match c.update(&state_at(here, 0.0), &r, 0.01) {
                Setpoint::Position {
                    position_enu_m,
                    velocity_ff_enu_mps,
                    yaw,
                } => {
                    // Never the far goal at once: a platform would fly to it at its own speed.
                    let step = position_enu_m - here;
                    assert!(
                        step.xy().norm() <= 0.0101 && step.z.abs() <= 0.0101,
                        "{tick}"
                    );
                    assert!(velocity_ff_enu_mps.xy().norm() <= 1.0 + 1e-9);
                    assert_eq!(yaw, YawTarget::Angle(0.5));
                    here = position_enu_m;
                }
                other => panic!("{other:?}"),
            }
        }
        assert!((here - goal).norm() < 1e-6, "{here}");
    }

    #[test]
    fn an_autopilot_closing_the_loop_is_never_asked_for_more_than_the_speed() {
        let autopilot = PositionLoop {
            gain_xy_per_s: 0.95,
            gain_z_per_s: 1.0,
        };
        let mut c = Controller::new(
            ControllerConfig::default(),
            AcceptedSetpoints {
                velocity: true,
                position: true,
                position_loop: Some(autopilot),
            },
        );
        // Following a path at 0.75 m/s while lagging 0.6 m behind the reference point: PX4's
        // correction alone would add 0.57 m/s.
        let r = MotionReference::Trajectory {
            position_enu_m: Vec3::new(0.6, 0.0, 1.0),
            velocity_enu_mps: Vec3::new(0.75, 0.0, 0.0),
            acceleration_enu_mps2: Vec3::zeros(),
            yaw: YawTarget::Angle(0.0),
            max_speed_mps: 0.75,
        };
        match c.update(&state_at(Vec3::new(0.0, 0.0, 1.0), 0.0), &r, 0.01) {
            Setpoint::Position {
                position_enu_m,
                velocity_ff_enu_mps,
                yaw,
            } => {
                let commanded =
                    velocity_ff_enu_mps + autopilot.correction(position_enu_m - Vec3::z());
                assert!((commanded.xy().norm() - 0.75).abs() < 1e-9, "{commanded}");
                assert_eq!(position_enu_m, Vec3::new(0.6, 0.0, 1.0));
                assert!(matches!(yaw, YawTarget::Rate(_)));
            }
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn a_trajectory_flown_on_velocities_keeps_within_its_speed_with_the_correction() {
        let mut c = Controller::new(
            ControllerConfig::default(),
            AcceptedSetpoints {
                velocity: true,
                position: true,
                position_loop: None,
            },
        );
        let r = MotionReference::Trajectory {
            position_enu_m: Vec3::new(1.0, 0.0, 0.0),
            velocity_enu_mps: Vec3::new(0.75, 0.0, 0.0),
            acceleration_enu_mps2: Vec3::new(1.0, 0.0, 0.0),
            yaw: YawTarget::Rate(0.0),
            max_speed_mps: 0.75,
        };
        let (v, _) = velocity_of(c.update(&state_at(Vec3::zeros(), 0.0), &r, 0.01));
        assert!((v.norm() - 0.75).abs() < 1e-9, "{v}");
    }

    /// A controller of `config` for a vehicle taking velocities, and the fastest velocity it
    /// sends in 5 s toward a goal 20 m off at 0.75 m/s.
    fn fastest_sent_to_a_far_goal(config: ControllerConfig) -> (Controller, f64) {
        let accepted = AcceptedSetpoints {
            velocity: true,
            position: true,
            position_loop: None,
        };
        let mut c = Controller::new(config, accepted);
        let far = MotionReference::Position {
            position_enu_m: Vec3::new(20.0, 0.0, 0.0),
            velocity_ff_enu_mps: Vec3::zeros(),
            yaw: YawTarget::Rate(0.0),
            max_speed_mps: 0.75,
        };
        let mut fastest: f64 = 0.0;
        for _ in 0..500 {
            let (v, _) = velocity_of(c.update(&state_at(Vec3::zeros(), 0.0), &far, 0.01));
            fastest = fastest.max(v.norm());
        }
        (c, fastest)
    }

    #[test]
    fn a_vehicle_that_overshoots_is_sent_the_share_of_the_speed_it_flies_within() {
        let (c, fastest) = fastest_sent_to_a_far_goal(ControllerConfig {
            velocity_overshoot: Some(0.15),
            ..ControllerConfig::default()
        });
        assert!((fastest - 0.75 / 1.15).abs() < 1e-9, "{fastest}");
        // The caps handed to the safety stage are the same share.
        assert!((c.caps(0.75).horizontal_mps - 0.75 / 1.15).abs() < 1e-12);
        // Without an overshoot the whole speed is sent.
        let plain = Controller::new(ControllerConfig::default(), c.accepted);
        assert_eq!(plain.caps(0.75).horizontal_mps, 0.75);
    }

    #[test]
    fn a_drifting_estimate_takes_its_drift_off_every_horizontal_cap() {
        let (c, fastest) = fastest_sent_to_a_far_goal(ControllerConfig {
            estimate_drift_mps: 0.03,
            ..ControllerConfig::default()
        });
        // Sent 0.72 m/s: with the estimate drifting at 0.03 m/s it flies 0.75 at most.
        assert!((fastest - 0.72).abs() < 1e-9, "{fastest}");
        assert!((c.caps(0.75).horizontal_mps - 0.72).abs() < 1e-12);
        // Vertical speeds do not drift.
        assert_eq!(c.caps(0.75).up_mps, 0.75);
        // With an overshoot too, and a limit slower than the drift still moves.
        assert!((commanded_horizontal_speed(0.75, 1.0 / 1.2, 0.03) - (0.625 - 0.03)).abs() < 1e-12);
        assert_eq!(commanded_horizontal_speed(0.04, 1.0, 0.05), 0.02);
    }

    #[test]
    fn a_vehicle_that_overshoots_turns_is_sent_the_share_of_the_turn_rate() {
        let accepted = AcceptedSetpoints {
            velocity: true,
            position: true,
            position_loop: None,
        };
        let config = ControllerConfig {
            yaw_rate_overshoot: Some(0.06),
            ..ControllerConfig::default()
        };
        let mut c = Controller::new(config, accepted);
        let here = state_at(Vec3::zeros(), 0.0);
        let turn = |yaw| MotionReference::Position {
            position_enu_m: Vec3::zeros(),
            velocity_ff_enu_mps: Vec3::zeros(),
            yaw,
            max_speed_mps: 0.75,
        };
        // A rate asked (explore's 0.15 rad/s), and a far heading turned to at the vehicle's limit.
        let (_, asked) = velocity_of(c.update(&here, &turn(YawTarget::Rate(-0.15)), 0.01));
        assert!((asked + 0.15 / 1.06).abs() < 1e-12, "{asked}");
        let (_, far) = velocity_of(c.update(&here, &turn(YawTarget::Angle(3.0)), 0.01));
        assert!((far - 1.5 / 1.06).abs() < 1e-12, "{far}");
        // Without an overshoot the rate is sent as asked.
        let mut plain = Controller::new(ControllerConfig::default(), accepted);
        let (_, plain_rate) = velocity_of(plain.update(&here, &turn(YawTarget::Rate(0.15)), 0.01));
        assert_eq!(plain_rate, 0.15);
    }

    #[test]
    fn a_lag_learnt_on_one_leg_does_not_push_across_the_next() {
        let mut c = Controller::new(
            ControllerConfig::default(),
            AcceptedSetpoints {
                velocity: true,
                position: true,
                position_loop: None,
            },
        );
        // 20 s along +x at the cap, the vehicle 0.25 m behind all the way (it cannot catch up).
        for k in 0..2000 {
            let x = 0.75 * k as f64 * 0.01;
            let r = MotionReference::Trajectory {
                position_enu_m: Vec3::new(x + 0.25, 0.0, 1.0),
                velocity_enu_mps: Vec3::new(0.75, 0.0, 0.0),
                acceleration_enu_mps2: Vec3::zeros(),
                yaw: YawTarget::Rate(0.0),
                max_speed_mps: 0.75,
            };
            c.update(&state_at(Vec3::new(x, 0.0, 1.0), 0.0), &r, 0.01);
        }
        // The path turns to +y at the vehicle, and the vehicle is on it.
        let at = Vec3::new(15.0, 0.0, 1.0);
        let r = MotionReference::Trajectory {
            position_enu_m: at,
            velocity_enu_mps: Vec3::new(0.0, 0.5, 0.0),
            acceleration_enu_mps2: Vec3::zeros(),
            yaw: YawTarget::Rate(0.0),
            max_speed_mps: 0.75,
        };
        let (v, _) = velocity_of(c.update(&state_at(at, 0.0), &r, 0.01));
        assert!(v.x.abs() < 0.02, "still pushed along the old leg: {v}");
        assert!((v.y - 0.5).abs() < 0.02, "{v}");
    }

    #[test]
    fn a_lag_learnt_while_moving_is_let_go_as_the_reference_stops() {
        let mut c = Controller::new(
            ControllerConfig::default(),
            AcceptedSetpoints {
                velocity: true,
                position: true,
                position_loop: None,
            },
        );
        // 20 s along +x at 1 m/s, the vehicle 0.2 m behind (an autopilot that answers late),
        // then the reference brakes to a stop over 1 s; the vehicle reaches the stop point.
        let mut x = 0.0;
        for k in 0..2100 {
            let speed = if k < 2000 {
                1.0
            } else {
                1.0 - (k - 2000) as f64 / 100.0
            };
            x += speed * 0.01;
            let r = MotionReference::Trajectory {
                position_enu_m: Vec3::new(x, 0.0, 1.0),
                velocity_enu_mps: Vec3::new(speed, 0.0, 0.0),
                acceleration_enu_mps2: Vec3::zeros(),
                yaw: YawTarget::Rate(0.0),
                max_speed_mps: 2.0,
            };
            let behind = if k < 2000 { 0.2 } else { 0.0 };
            c.update(&state_at(Vec3::new(x - behind, 0.0, 1.0), 0.0), &r, 0.01);
        }
        let r = MotionReference::Trajectory {
            position_enu_m: Vec3::new(x, 0.0, 1.0),
            velocity_enu_mps: Vec3::zeros(),
            acceleration_enu_mps2: Vec3::zeros(),
            yaw: YawTarget::Rate(0.0),
            max_speed_mps: 2.0,
        };
        let (v, _) = velocity_of(c.update(&state_at(Vec3::new(x, 0.0, 1.0), 0.0), &r, 0.01));
        assert!(v.norm() < 0.02, "still pushed on past the stop: {v}");
    }

    #[test]
    fn trajectory_feed_forward_passes_through_when_on_track() {
        let mut c = Controller::new(
            ControllerConfig::default(),
            AcceptedSetpoints {
                velocity: true,
                position: true,
                position_loop: None,
            },
        );
        let r = MotionReference::Trajectory {
            position_enu_m: Vec3::new(1.0, 1.0, 1.0),
            velocity_enu_mps: Vec3::new(0.5, 0.0, 0.0),
            acceleration_enu_mps2: Vec3::zeros(),
            yaw: YawTarget::Rate(0.0),
            max_speed_mps: f64::INFINITY,
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
                position_loop: None,
            },
        );
        let r = MotionReference::Trajectory {
            position_enu_m: Vec3::zeros(),
            velocity_enu_mps: Vec3::new(1.0, 0.0, 0.0),
            acceleration_enu_mps2: Vec3::new(2.0, 0.0, 0.0),
            yaw: YawTarget::Rate(0.0),
            max_speed_mps: f64::INFINITY,
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
                position_loop: None,
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
