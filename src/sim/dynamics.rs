//! Multirotor dynamics behind a velocity-controlled autopilot, as a point mass with heading.
//!
//! In: a velocity and yaw-rate command, wind, and a noise sample. Out: the next state. What it
//! models, so controller bugs show: first-order velocity response, acceleration limited by the
//! tilt limit, horizontal/vertical speed limits, yaw-rate limit, air drag toward the wind
//! velocity, gravity when the motors stop, and ground contact.

use crate::types::{wrap_angle_rad, Vec3, DEFAULT_VEHICLE_RADIUS_M};
use serde::{Deserialize, Serialize};

const GRAVITY_MPS2: f64 = 9.81;

#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MultirotorParams {
    pub max_horizontal_speed_mps: f64,
    pub max_up_speed_mps: f64,
    pub max_down_speed_mps: f64,
    /// Largest tilt the attitude loop allows (rad); bounds horizontal acceleration.
    pub max_tilt_rad: f64,
    pub max_vertical_acceleration_mps2: f64,
    /// Time constant of the autopilot's velocity loop (s).
    pub velocity_time_constant_s: f64,
    pub max_yaw_rate_radps: f64,
    pub yaw_time_constant_s: f64,
    /// Drag pulling the vehicle toward the wind velocity (1/s).
    pub drag_per_s: f64,
    /// Collision radius (m).
    pub radius_m: f64,
}

impl Default for MultirotorParams {
    fn default() -> Self {
        Self {
            max_horizontal_speed_mps: 10.0,
            max_up_speed_mps: 3.0,
            max_down_speed_mps: 1.5,
            max_tilt_rad: 35f64.to_radians(),
            max_vertical_acceleration_mps2: 4.0,
            velocity_time_constant_s: 0.25,
            max_yaw_rate_radps: 2.0,
            yaw_time_constant_s: 0.1,
            drag_per_s: 0.3,
            radius_m: DEFAULT_VEHICLE_RADIUS_M,
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct RigidState {
    pub position_m: Vec3,
    pub velocity_mps: Vec3,
    pub acceleration_mps2: Vec3,
    pub yaw_rad: f64,
    pub yaw_rate_radps: f64,
}

impl RigidState {
    pub fn on_ground(&self) -> bool {
        self.position_m.z <= 1e-3
    }
    /// Roll and pitch (rad) that produce the current horizontal acceleration.
    pub fn tilt_rad(&self) -> (f64, f64) {
        let (s, c) = self.yaw_rad.sin_cos();
        let ax = c * self.acceleration_mps2.x + s * self.acceleration_mps2.y;
        let ay = -s * self.acceleration_mps2.x + c * self.acceleration_mps2.y;
        ((-ay / GRAVITY_MPS2).atan(), (ax / GRAVITY_MPS2).atan())
    }
}

/// What drives the motors this step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Drive {
    /// Motors off: falls, or rests on the ground.
    Off,
    Velocity {
        velocity_enu_mps: Vec3,
        yaw_rate_radps: f64,
    },
}

/// Advances `s` by `dt_s`. `disturbance_mps2` is an extra acceleration (noise).
pub fn step(
    s: &mut RigidState,
    p: &MultirotorParams,
    drive: Drive,
    wind_mps: &Vec3,
    disturbance_mps2: &Vec3,
    dt_s: f64,
) {
    let lifting =
        matches!(drive, Drive::Velocity { velocity_enu_mps, .. } if velocity_enu_mps.z > 0.0);
    if s.on_ground() && !lifting {
        // Resting on the ground: no sinking, no sliding, no turning.
        s.position_m.z = 0.0;
        s.velocity_mps = Vec3::zeros();
        s.acceleration_mps2 = Vec3::zeros();
        s.yaw_rate_radps = 0.0;
        return;
    }
    let accel = match drive {
        Drive::Off => {
            Vec3::new(-s.velocity_mps.x, -s.velocity_mps.y, 0.0) * p.drag_per_s
                - Vec3::new(0.0, 0.0, GRAVITY_MPS2)
        }
        Drive::Velocity {
            velocity_enu_mps,
            yaw_rate_radps,
        } => {
            let cmd = limit_velocity(velocity_enu_mps, p);
            let mut a = (cmd - s.velocity_mps) / p.velocity_time_constant_s.max(1e-3);
            let a_h_max = GRAVITY_MPS2 * p.max_tilt_rad.tan();
            let a_h = a.xy().norm();
            if a_h > a_h_max {
                let k = a_h_max / a_h;
                a.x *= k;
                a.y *= k;
            }
            a.z = a.z.clamp(
                -p.max_vertical_acceleration_mps2,
                p.max_vertical_acceleration_mps2,
            );
            let rate_cmd = yaw_rate_radps.clamp(-p.max_yaw_rate_radps, p.max_yaw_rate_radps);
            s.yaw_rate_radps +=
                (rate_cmd - s.yaw_rate_radps) * (dt_s / p.yaw_time_constant_s.max(dt_s));
            // The autopilot's velocity loop cancels drag in still air; wind leaves a steady push.
            a + wind_mps * p.drag_per_s + disturbance_mps2
        }
    };
    if matches!(drive, Drive::Off) {
        s.yaw_rate_radps = 0.0;
    }
    s.velocity_mps += accel * dt_s;
    s.position_m += s.velocity_mps * dt_s;
    s.yaw_rad = wrap_angle_rad(s.yaw_rad + s.yaw_rate_radps * dt_s);
    s.acceleration_mps2 = accel;
    if s.position_m.z <= 0.0 {
        // Touchdown.
        s.position_m.z = 0.0;
        if s.velocity_mps.z < 0.0 {
            s.velocity_mps = Vec3::zeros();
            s.acceleration_mps2 = Vec3::zeros();
        }
    }
}

fn limit_velocity(v: Vec3, p: &MultirotorParams) -> Vec3 {
    let h = v.xy();
    let n = h.norm();
    let h = if n > p.max_horizontal_speed_mps {
        h * (p.max_horizontal_speed_mps / n)
    } else {
        h
    };
    Vec3::new(
        h.x,
        h.y,
        v.z.clamp(-p.max_down_speed_mps, p.max_up_speed_mps),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(s: &mut RigidState, drive: Drive, seconds: f64) {
        let p = MultirotorParams::default();
        let steps = (seconds / 0.01) as usize;
        for _ in 0..steps {
            step(s, &p, drive, &Vec3::zeros(), &Vec3::zeros(), 0.01);
        }
    }

    #[test]
    fn velocity_converges_with_first_order_lag() {
        let mut s = RigidState {
            position_m: Vec3::new(0.0, 0.0, 5.0),
            ..Default::default()
        };
        run(
            &mut s,
            Drive::Velocity {
                velocity_enu_mps: Vec3::new(2.0, 0.0, 0.0),
                yaw_rate_radps: 0.0,
            },
            0.25,
        );
        // After one time constant: about 63 % of the step (acceleration limit not reached).
        assert!(
            (s.velocity_mps.x - 2.0 * 0.63).abs() < 0.1,
            "{}",
            s.velocity_mps.x
        );
        run(
            &mut s,
            Drive::Velocity {
                velocity_enu_mps: Vec3::new(2.0, 0.0, 0.0),
                yaw_rate_radps: 0.0,
            },
            3.0,
        );
        assert!((s.velocity_mps.x - 2.0).abs() < 1e-3);
    }

    #[test]
    fn speed_and_acceleration_are_limited() {
        let p = MultirotorParams::default();
        let mut s = RigidState {
            position_m: Vec3::new(0.0, 0.0, 5.0),
            ..Default::default()
        };
        step(
            &mut s,
            &p,
            Drive::Velocity {
                velocity_enu_mps: Vec3::new(100.0, 0.0, 100.0),
                yaw_rate_radps: 9.0,
            },
            &Vec3::zeros(),
            &Vec3::zeros(),
            0.01,
        );
        let a_h_max = GRAVITY_MPS2 * p.max_tilt_rad.tan();
        assert!(s.acceleration_mps2.x <= a_h_max + 1e-9);
        run(
            &mut s,
            Drive::Velocity {
                velocity_enu_mps: Vec3::new(100.0, 0.0, 100.0),
                yaw_rate_radps: 9.0,
            },
            10.0,
        );
        assert!((s.velocity_mps.x - p.max_horizontal_speed_mps).abs() < 0.01);
        assert!((s.velocity_mps.z - p.max_up_speed_mps).abs() < 0.01);
        assert!((s.yaw_rate_radps - p.max_yaw_rate_radps).abs() < 0.01);
    }

    #[test]
    fn motors_off_falls_and_rests_on_the_ground() {
        let mut s = RigidState {
            position_m: Vec3::new(0.0, 0.0, 2.0),
            ..Default::default()
        };
        run(&mut s, Drive::Off, 2.0);
        assert_eq!(s.position_m.z, 0.0);
        assert_eq!(s.velocity_mps, Vec3::zeros());
    }

    #[test]
    fn ground_blocks_descent_commands() {
        let mut s = RigidState::default();
        run(
            &mut s,
            Drive::Velocity {
                velocity_enu_mps: Vec3::new(1.0, 0.0, -1.0),
                yaw_rate_radps: 0.0,
            },
            1.0,
        );
        assert_eq!(
            s.position_m,
            Vec3::zeros(),
            "no sinking or sliding on the ground"
        );
    }

    #[test]
    fn wind_pushes_a_hovering_vehicle() {
        let p = MultirotorParams::default();
        let mut s = RigidState {
            position_m: Vec3::new(0.0, 0.0, 5.0),
            ..Default::default()
        };
        for _ in 0..500 {
            step(
                &mut s,
                &p,
                Drive::Velocity {
                    velocity_enu_mps: Vec3::zeros(),
                    yaw_rate_radps: 0.0,
                },
                &Vec3::new(5.0, 0.0, 0.0),
                &Vec3::zeros(),
                0.01,
            );
        }
        assert!(
            s.velocity_mps.x > 0.1,
            "steady drift downwind: {}",
            s.velocity_mps.x
        );
    }
}
