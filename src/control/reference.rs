//! What behaviors ask of the controller (the setpoint vocabulary it answers with is in `types`).

use crate::types::Vec3;
pub use crate::types::{AcceptedSetpoints, Setpoint, YawTarget};
use serde::{Deserialize, Serialize};

/// A motion reference in the `earth` frame, produced by a behavior each tick.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", tag = "mode")]
pub enum MotionReference {
    /// Go to and hold a position, approaching not faster than `max_speed_mps`; the target's own
    /// velocity (a point in a moving frame) is added as feed-forward.
    Position {
        position_enu_m: Vec3,
        velocity_ff_enu_mps: Vec3,
        yaw: YawTarget,
        max_speed_mps: f64,
    },
    /// Fly this velocity.
    Velocity {
        velocity_enu_mps: Vec3,
        yaw: YawTarget,
    },
    /// Track a moving reference point with feed-forward velocity and acceleration, never
    /// commanding more than `max_speed_mps` (the correction toward the point included).
    Trajectory {
        position_enu_m: Vec3,
        velocity_enu_mps: Vec3,
        acceleration_enu_mps2: Vec3,
        yaw: YawTarget,
        max_speed_mps: f64,
    },
}

impl MotionReference {
    /// The speed the commanded velocity must stay within (m/s); a velocity reference is
    /// limited by the vehicle's limits alone.
    pub fn max_speed_mps(&self) -> f64 {
        match self {
            Self::Position { max_speed_mps, .. } | Self::Trajectory { max_speed_mps, .. } => {
                *max_speed_mps
            }
            Self::Velocity { .. } => f64::INFINITY,
        }
    }

    /// The point the reference holds the vehicle at, or tracks it along (`None` for a
    /// velocity).
    pub fn held_at(&self) -> Option<Vec3> {
        match self {
            Self::Position { position_enu_m, .. } | Self::Trajectory { position_enu_m, .. } => {
                Some(*position_enu_m)
            }
            Self::Velocity { .. } => None,
        }
    }

    /// This reference flown no faster than `speed_mps`: a lower `max_speed_mps`, a velocity
    /// scaled down to it (a behavior's own speed limit over the holds it borrows, whose speed is
    /// `hold_speed_mps`).
    pub fn at_most(self, speed_mps: f64) -> Self {
        match self {
            Self::Position {
                position_enu_m,
                velocity_ff_enu_mps,
                yaw,
                max_speed_mps,
            } => Self::Position {
                position_enu_m,
                velocity_ff_enu_mps,
                yaw,
                max_speed_mps: max_speed_mps.min(speed_mps),
            },
            Self::Trajectory {
                position_enu_m,
                velocity_enu_mps,
                acceleration_enu_mps2,
                yaw,
                max_speed_mps,
            } => Self::Trajectory {
                position_enu_m,
                velocity_enu_mps,
                acceleration_enu_mps2,
                yaw,
                max_speed_mps: max_speed_mps.min(speed_mps),
            },
            Self::Velocity {
                velocity_enu_mps,
                yaw,
            } => {
                let speed = velocity_enu_mps.norm();
                let scale = if speed > speed_mps && speed > 0.0 {
                    speed_mps / speed
                } else {
                    1.0
                };
                Self::Velocity {
                    velocity_enu_mps: velocity_enu_mps * scale,
                    yaw,
                }
            }
        }
    }

    /// Hold `position_enu_m` with heading `yaw_rad`.
    pub fn hold(position_enu_m: Vec3, yaw_rad: f64, max_speed_mps: f64) -> Self {
        Self::Position {
            position_enu_m,
            velocity_ff_enu_mps: Vec3::zeros(),
            yaw: YawTarget::Angle(yaw_rad),
            max_speed_mps,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn at_most_lowers_a_speed_limit_and_never_raises_one() {
        let hold = MotionReference::hold(Vec3::new(1.0, 2.0, 1.0), 0.5, 1.0);
        assert_eq!(hold.at_most(0.75).max_speed_mps(), 0.75);
        assert_eq!(hold.at_most(2.0).max_speed_mps(), 1.0);
        assert_eq!(hold.at_most(0.75).held_at(), hold.held_at());
        let fast = MotionReference::Velocity {
            velocity_enu_mps: Vec3::new(3.0, 4.0, 0.0),
            yaw: YawTarget::Rate(0.1),
        };
        match fast.at_most(0.5) {
            MotionReference::Velocity {
                velocity_enu_mps,
                yaw,
            } => {
                assert!((velocity_enu_mps - Vec3::new(0.3, 0.4, 0.0)).norm() < 1e-12);
                assert_eq!(yaw, YawTarget::Rate(0.1));
            }
            other => panic!("{other:?}"),
        }
        assert_eq!(fast.at_most(10.0), fast);
    }
}
