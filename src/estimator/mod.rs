//! State estimation and frames.
//!
//! In: platform odometry, simulator ground truth or external poses (motion capture).
//! Out: one [`EstimatedState`] per tick (pose and twist of `base_link` in `earth`, validity
//! flags, reset counter) and the frame tree updated with `base_link`.
//!
//! The plugin is chosen in config (`estimator.plugin`): `ground_truth`, `autopilot_odometry`
//! or `external_pose`.

pub mod frames;
pub mod geodetic;
pub mod map_correction;

use crate::types::{EstimatedState, Pose, Validity};
use serde::{Deserialize, Serialize};
use std::time::Duration;

pub use crate::types::Measurement;

#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum EstimatorPlugin {
    #[default]
    GroundTruth,
    AutopilotOdometry,
    ExternalPose,
}

/// An estimator plugin: consumes the measurements of one tick, returns the current estimate.
pub trait Estimator: Send {
    /// Called once per tick with every measurement received since the last tick (may be none).
    /// Returns the estimate at `now`; with nothing usable yet, validity flags are false.
    fn update(&mut self, now: Duration, measurements: &[Measurement]) -> EstimatedState;
}

pub fn build(plugin: EstimatorPlugin) -> Box<dyn Estimator> {
    match plugin {
        EstimatorPlugin::GroundTruth => Box::new(PassThrough::new(Source::GroundTruth)),
        EstimatorPlugin::AutopilotOdometry => Box::new(PassThrough::new(Source::Autopilot)),
        EstimatorPlugin::ExternalPose => Box::new(ExternalPoseEstimator::default()),
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Source {
    GroundTruth,
    Autopilot,
}

/// Forwards the simulator's ground truth or the autopilot's odometry unchanged.
struct PassThrough {
    source: Source,
    last: EstimatedState,
}

impl PassThrough {
    fn new(source: Source) -> Self {
        Self {
            source,
            last: EstimatedState::default(),
        }
    }
}

impl Estimator for PassThrough {
    fn update(&mut self, now: Duration, measurements: &[Measurement]) -> EstimatedState {
        for m in measurements {
            match (*m, self.source) {
                (
                    Measurement::GroundTruth {
                        pose,
                        velocity_enu_mps,
                        angular_velocity_flu_radps,
                    },
                    Source::GroundTruth,
                ) => {
                    self.last = EstimatedState {
                        stamp: now,
                        pose,
                        velocity_enu_mps,
                        angular_velocity_flu_radps,
                        valid: Validity::ALL,
                        reset_counter: 0,
                    };
                }
                (
                    Measurement::AutopilotOdometry {
                        pose,
                        velocity_enu_mps,
                        angular_velocity_flu_radps,
                        valid,
                        reset_counter,
                    },
                    Source::Autopilot,
                ) => {
                    self.last = EstimatedState {
                        stamp: now,
                        pose,
                        velocity_enu_mps,
                        angular_velocity_flu_radps,
                        valid,
                        reset_counter,
                    };
                }
                _ => {}
            }
        }
        self.last
    }
}

/// Differentiates external poses (motion capture) into a velocity with a low-pass filter.
#[derive(Default)]
struct ExternalPoseEstimator {
    last: Option<(Pose, Duration)>,
    state: EstimatedState,
}

/// Poses older than this make the estimate invalid.
const EXTERNAL_POSE_TIMEOUT: Duration = Duration::from_millis(500);
/// Weight of a new velocity sample in the low-pass filter.
const VELOCITY_FILTER_ALPHA: f64 = 0.5;

impl Estimator for ExternalPoseEstimator {
    fn update(&mut self, now: Duration, measurements: &[Measurement]) -> EstimatedState {
        for m in measurements {
            if let Measurement::ExternalPose { pose, stamp } = *m {
                if let Some((prev, prev_stamp)) = self.last {
                    let dt = stamp.saturating_sub(prev_stamp).as_secs_f64();
                    if dt > 1e-4 {
                        let v = (pose.position_m - prev.position_m) / dt;
                        self.state.velocity_enu_mps = self.state.velocity_enu_mps
                            * (1.0 - VELOCITY_FILTER_ALPHA)
                            + v * VELOCITY_FILTER_ALPHA;
                        self.state.valid.velocity = true;
                    }
                }
                self.state.pose = pose;
                self.state.stamp = stamp;
                self.state.valid.position = true;
                self.state.valid.attitude = true;
                self.last = Some((pose, stamp));
            }
        }
        if now.saturating_sub(self.state.stamp) > EXTERNAL_POSE_TIMEOUT {
            self.state.valid = Validity::default();
        }
        self.state
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::types::Vec3;

    #[test]
    fn external_pose_gives_velocity_and_times_out() {
        let mut est = build(EstimatorPlugin::ExternalPose);
        let p0 = Pose::from_position_yaw(Vec3::zeros(), 0.0);
        let p1 = Pose::from_position_yaw(Vec3::new(0.1, 0.0, 0.0), 0.0);
        est.update(
            Duration::ZERO,
            &[Measurement::ExternalPose {
                pose: p0,
                stamp: Duration::ZERO,
            }],
        );
        let s = est.update(
            Duration::from_millis(100),
            &[Measurement::ExternalPose {
                pose: p1,
                stamp: Duration::from_millis(100),
            }],
        );
        assert!(s.valid.position && s.valid.velocity);
        assert!(
            (s.velocity_enu_mps.x - 0.5).abs() < 1e-9,
            "filtered 1 m/s sample: {}",
            s.velocity_enu_mps
        );
        let stale = est.update(Duration::from_secs(2), &[]);
        assert!(!stale.valid.position);
    }

    #[test]
    fn pass_through_ignores_other_sources() {
        let mut est = build(EstimatorPlugin::AutopilotOdometry);
        let gt = Measurement::GroundTruth {
            pose: Pose::identity(),
            velocity_enu_mps: Vec3::zeros(),
            angular_velocity_flu_radps: Vec3::zeros(),
        };
        assert!(!est.update(Duration::ZERO, &[gt]).valid.position);
    }
}
