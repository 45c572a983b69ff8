//! What a platform measures for the estimator (already ENU/FLU).

use super::{Pose, Validity, Vec3};
use std::time::Duration;

/// One measurement the estimator may use, as the platform delivers it (already ENU/FLU).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Measurement {
    /// Exact state from the simulator.
    GroundTruth {
        pose: Pose,
        velocity_enu_mps: Vec3,
        angular_velocity_flu_radps: Vec3,
    },
    /// The autopilot's own estimate (LOCAL_POSITION_NED / ODOMETRY / ATTITUDE, converted).
    AutopilotOdometry {
        pose: Pose,
        velocity_enu_mps: Vec3,
        angular_velocity_flu_radps: Vec3,
        valid: Validity,
        reset_counter: u32,
    },
    /// A pose from outside (motion capture), with the time it was taken.
    ExternalPose { pose: Pose, stamp: Duration },
}
