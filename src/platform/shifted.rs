//! A platform whose local frame sits elsewhere in the fleet's shared ENU frame: each autopilot
//! of a fleet counts positions from where its own estimator started, so `kestrel run` with a
//! `[[vehicle]]` list wraps each in a [`Shifted`] by that vehicle's `origin_enu_m`.
//!
//! In: the core's setpoints (shared frame) and the inner platform's feedback (its local frame).
//! Out: position setpoints moved into the local frame (minus the origin), and positions in
//! measurements and scans moved into the shared frame (plus the origin). Velocities, attitudes
//! and yaw are unchanged: autopilot local frames are north-aligned, a pure translation apart.

use super::{Capabilities, Platform, PlatformFeedback, PlatformRequest};
use crate::types::{Measurement, Setpoint, Vec3};
use std::time::Duration;

/// `inner`, its local frame origin at `origin_enu_m` in the shared frame.
pub struct Shifted {
    inner: Box<dyn Platform>,
    origin_enu_m: Vec3,
}

impl Shifted {
    pub fn new(inner: Box<dyn Platform>, origin_enu_m: Vec3) -> Self {
        Self {
            inner,
            origin_enu_m,
        }
    }
}

impl Platform for Shifted {
    fn capabilities(&self) -> Capabilities {
        self.inner.capabilities()
    }

    fn poll(&mut self, now: Duration) -> PlatformFeedback {
        let mut feedback = self.inner.poll(now);
        let o = self.origin_enu_m;
        for m in &mut feedback.measurements {
            match m {
                Measurement::GroundTruth { pose, .. }
                | Measurement::AutopilotOdometry { pose, .. }
                | Measurement::ExternalPose { pose, .. } => pose.position_m += o,
            }
        }
        for scan in &mut feedback.scans {
            scan.origin_enu_m += o;
        }
        feedback
    }

    fn command(&mut self, now: Duration, setpoint: Option<Setpoint>, requests: &[PlatformRequest]) {
        let local = setpoint.map(|s| match s {
            Setpoint::Position {
                position_enu_m,
                velocity_ff_enu_mps,
                yaw,
            } => Setpoint::Position {
                position_enu_m: position_enu_m - self.origin_enu_m,
                velocity_ff_enu_mps,
                yaw,
            },
            velocity @ Setpoint::Velocity { .. } => velocity,
        });
        self.inner.command(now, local, requests);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::types::{Pose, RangeScan, YawTarget};
    use std::sync::{Arc, Mutex};

    /// Stands at `at` in its own frame, sees one scan from there, keeps the last setpoint.
    struct Local {
        at: Vec3,
        last: Arc<Mutex<Option<Setpoint>>>,
    }

    impl Platform for Local {
        fn capabilities(&self) -> Capabilities {
            Capabilities::setpoints_only()
        }
        fn poll(&mut self, _now: Duration) -> PlatformFeedback {
            let pose = Pose {
                position_m: self.at,
                orientation: nalgebra::UnitQuaternion::identity(),
            };
            PlatformFeedback {
                measurements: vec![Measurement::AutopilotOdometry {
                    pose,
                    velocity_enu_mps: Vec3::new(1.0, 0.0, 0.0),
                    angular_velocity_flu_radps: Vec3::zeros(),
                    valid: Default::default(),
                    reset_counter: 0,
                }],
                scans: vec![RangeScan {
                    origin_enu_m: self.at,
                    yaw_rad: 0.5,
                    range_min_m: 0.05,
                    range_max_m: 4.0,
                    beams: Vec::new(),
                }],
                ..PlatformFeedback::default()
            }
        }
        fn command(&mut self, _now: Duration, setpoint: Option<Setpoint>, _r: &[PlatformRequest]) {
            *self.last.lock().unwrap() = setpoint;
        }
    }

    #[test]
    fn positions_go_out_shifted_and_position_setpoints_come_back() {
        let origin = Vec3::new(3.0, -2.0, 0.5);
        let last = Arc::new(Mutex::new(None));
        let local = Local {
            at: Vec3::new(1.0, 1.0, 2.0),
            last: last.clone(),
        };
        let mut shifted = Shifted::new(Box::new(local), origin);
        let feedback = shifted.poll(Duration::ZERO);
        let Some(Measurement::AutopilotOdometry {
            pose,
            velocity_enu_mps,
            ..
        }) = feedback.measurements.first()
        else {
            panic!("{feedback:?}");
        };
        assert_eq!(pose.position_m, Vec3::new(4.0, -1.0, 2.5));
        assert_eq!(*velocity_enu_mps, Vec3::new(1.0, 0.0, 0.0));
        assert_eq!(feedback.scans[0].origin_enu_m, Vec3::new(4.0, -1.0, 2.5));
        assert_eq!(feedback.scans[0].yaw_rad, 0.5);

        let yaw = YawTarget::Angle(0.3);
        let to = Setpoint::Position {
            position_enu_m: Vec3::new(4.0, -1.0, 2.5),
            velocity_ff_enu_mps: Vec3::new(0.0, 1.0, 0.0),
            yaw,
        };
        shifted.command(Duration::ZERO, Some(to), &[]);
        let expected = Setpoint::Position {
            position_enu_m: Vec3::new(1.0, 1.0, 2.0),
            velocity_ff_enu_mps: Vec3::new(0.0, 1.0, 0.0),
            yaw,
        };
        assert_eq!(*last.lock().unwrap(), Some(expected));
        let climb = Setpoint::Velocity {
            velocity_enu_mps: Vec3::new(0.0, 0.0, 1.0),
            yaw,
        };
        shifted.command(Duration::ZERO, Some(climb), &[]);
        assert_eq!(*last.lock().unwrap(), Some(climb));
    }
}
